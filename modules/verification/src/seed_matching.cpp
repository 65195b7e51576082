#include "ignav/verification/seed_matching.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include <fmt/format.h>

#include "ignav/verification/assignment.hpp"

namespace ignav::verification {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr std::size_t kMaxTargets = 256;
constexpr std::size_t kMaxSeeds = 512;

std::string at(const Eigen::Vector3d& p) {
  return fmt::format("({:.2f}, {:.2f}, {:.2f})", p.x(), p.y(), p.z());
}

Error invalid(const std::string& message, const std::string& reason) {
  return makeError(ErrorCode::kInvalidArgument, "seed matching: " + message, reason);
}

Status checkInput(const std::vector<TargetPoint>& targets,
                  const std::vector<Eigen::Vector3d>& seeds, const MatchOptions& o) {
  if (!(o.max_distance_mm > 0.0) || !std::isfinite(o.max_distance_mm)) {
    return invalid(
        fmt::format("max_distance_mm = {:g} must be finite and positive", o.max_distance_mm),
        "bad_option");
  }
  if (!(o.localisation_sd_mm >= 0.0) || !std::isfinite(o.localisation_sd_mm)) {
    return invalid(fmt::format("localisation_sd_mm = {:g} must be finite and not negative",
                               o.localisation_sd_mm),
                   "bad_option");
  }
  if (!(o.min_margin_sd >= 0.0) || !std::isfinite(o.min_margin_sd)) {
    return invalid(
        fmt::format("min_margin_sd = {:g} must be finite and not negative", o.min_margin_sd),
        "bad_option");
  }
  if (targets.size() > kMaxTargets) {
    return invalid(fmt::format("{} targets, at most {}", targets.size(), kMaxTargets), "too_many");
  }
  if (seeds.size() > kMaxSeeds) {
    return invalid(fmt::format("{} seeds, at most {}", seeds.size(), kMaxSeeds), "too_many");
  }
  std::set<std::uint32_t> ids;
  for (const auto& t : targets) {
    if (!t.mm.allFinite())
      return invalid(fmt::format("target {} has a non-finite coordinate", t.id), "non_finite");
    if (!ids.insert(t.id).second)
      return invalid(fmt::format("target id {} given twice", t.id), "duplicate_target");
  }
  for (std::size_t j = 0; j < seeds.size(); ++j) {
    if (!seeds[j].allFinite())
      return invalid(fmt::format("seed {} has a non-finite coordinate", j + 1), "non_finite");
  }
  if (targets.empty()) {
    return makeError(ErrorCode::kInvalidArgument, "seed matching: no targets to match seeds to",
                     "no_targets");
  }
  if (seeds.empty()) {
    return makeError(ErrorCode::kDegenerate,
                     fmt::format("no seeds found: nothing to match to the {} targets; check the "
                                 "confirmation scan and the seed search, or place them by hand",
                                 targets.size()),
                     "no_seeds");
  }
  return Ok{};
}

}  // namespace

Expected<SeedMatch> matchSeeds(const std::vector<TargetPoint>& targets,
                               const std::vector<Eigen::Vector3d>& seeds,
                               const MatchOptions& options) {
  if (auto ok = checkInput(targets, seeds, options); !ok) return ok.error();
  const std::size_t n = targets.size(), m = seeds.size(), size = n + m;
  // Rows: the targets, then "seed j is left over"; columns: the seeds, then "target i is
  // missing". Leaving a target and a seed both unpaired costs max_distance², so a pair closer
  // than max_distance is always preferred to none; a pair beyond it is forbidden.
  const double d_max = options.max_distance_mm, unpaired = 0.5 * d_max * d_max;
  Eigen::MatrixXd cost = Eigen::MatrixXd::Constant(static_cast<Eigen::Index>(size),
                                                   static_cast<Eigen::Index>(size), kInf);
  auto c = [&](std::size_t i, std::size_t j) -> double& {
    return cost(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
  };
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < m; ++j) {
      const double d = (seeds[j] - targets[i].mm).norm();
      if (d <= d_max) c(i, j) = d * d;
    }
    c(i, m + i) = unpaired;
  }
  for (std::size_t j = 0; j < m; ++j) {
    c(n + j, j) = unpaired;
    for (std::size_t i = 0; i < n; ++i)
      c(n + j, m + i) = 0.0;
  }
  auto solved = assignWithAlternatives(cost);
  if (!solved) {
    return makeError(ErrorCode::kInternal, "seed matching: " + solved.error().message);
  }
  // Who owns each seed in an assignment: a target index, or n for none.
  auto owners = [&](const Assignment& a) {
    std::vector<std::size_t> owner(m, n);
    for (std::size_t i = 0; i < n; ++i) {
      if (a.column_of_row[i] < m) owner[a.column_of_row[i]] = i;
    }
    return owner;
  };
  const Assignment& best = solved->best;
  const auto best_owner = owners(best);

  SeedMatch match;
  for (std::size_t i = 0; i < n; ++i) {
    TargetMatch t;
    t.target_id = targets[i].id;
    const std::size_t j = best.column_of_row[i];
    if (j < m) {
      t.seed = j;
      t.distance_mm = (seeds[j] - targets[i].mm).norm();
      match.total_squared_distance_mm2 += t.distance_mm * t.distance_mm;
    } else {
      match.missing_targets.push_back(i);
    }
    match.targets.push_back(t);
  }
  for (std::size_t j = 0; j < m; ++j) {
    if (best_owner[j] == n) match.extra_seeds.push_back(j);
  }
  auto seedList = [&](const std::vector<std::size_t>& list) {
    std::string s;
    for (std::size_t j : list)
      s += (s.empty() ? "" : ", ") + fmt::format("seed {} at {}", j + 1, at(seeds[j]));
    return s;
  };
  if (m > n && !options.allow_extra_seeds) {
    return makeError(ErrorCode::kDegenerate,
                     fmt::format("{} seeds for {} targets, {} more than were deposited: the best "
                                 "assignment leaves {} over (mm); reject what is not a seed of "
                                 "this plan, or allow extra seeds",
                                 m, n, m - n, seedList(match.extra_seeds)),
                     "more_seeds_than_targets");
  }

  // How distinct the optimum is, per target. The difference in total squared distance between
  // the alternative and the optimum moves with the seeds' positions: its gradient at seed j is
  // 2(s - t_alt) - 2(s - t_best) (a term only where that seed is paired), so a localisation
  // error of SD sigma per coordinate gives it the SD sigma * sqrt(sum |gradient|²).
  const double sigma = options.localisation_sd_mm;
  std::size_t worst = n;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& alt = solved->alternative[i];
    if (!alt) continue;
    TargetMatch& t = match.targets[i];
    const std::size_t j = alt->column_of_row[i];
    t.runner_up_seed = j < m ? std::optional<std::size_t>(j) : std::nullopt;
    t.runner_up_extra_mm2 = std::max(0.0, alt->cost - best.cost);
    const auto alt_owner = owners(*alt);
    double gradient_sq = 0.0;
    for (std::size_t s = 0; s < m; ++s) {
      if (alt_owner[s] == best_owner[s]) continue;
      Eigen::Vector3d g = Eigen::Vector3d::Zero();
      if (alt_owner[s] < n) g += 2.0 * (seeds[s] - targets[alt_owner[s]].mm);
      if (best_owner[s] < n) g -= 2.0 * (seeds[s] - targets[best_owner[s]].mm);
      gradient_sq += g.squaredNorm();
    }
    const double sd = sigma * std::sqrt(gradient_sq);
    t.runner_up_margin_sd =
        sd > 0.0 ? t.runner_up_extra_mm2 / sd : (t.runner_up_extra_mm2 > 0.0 ? kInf : 0.0);
    if (t.runner_up_margin_sd < match.min_margin_sd) {
      match.min_margin_sd = t.runner_up_margin_sd;
      worst = i;
    }
  }
  if (worst < n && match.min_margin_sd <= options.min_margin_sd) {
    const TargetMatch& t = match.targets[worst];
    const auto& alt = *solved->alternative[worst];
    std::string exchanged;
    for (std::size_t i = 0; i < n; ++i) {
      if (alt.column_of_row[i] == best.column_of_row[i]) continue;
      auto seedName = [&](std::size_t j) {
        return j < m ? fmt::format("seed {} at {}", j + 1, at(seeds[j])) : std::string("none");
      };
      exchanged += (exchanged.empty() ? "" : "; ") +
                   fmt::format("target {}: {} instead of {}", targets[i].id,
                               seedName(alt.column_of_row[i]), seedName(best.column_of_row[i]));
    }
    return makeError(
        ErrorCode::kDegenerate,
        fmt::format("ambiguous match at target {}: another assignment ({}) costs only {:.2f} mm² "
                    "more total squared distance, {:.1f} SD of what a {:.2f} mm localisation "
                    "error makes of that difference ({:g} needed); confirm these seeds by hand",
                    t.target_id, exchanged, t.runner_up_extra_mm2, t.runner_up_margin_sd, sigma,
                    options.min_margin_sd),
        "ambiguous_match");
  }

  match.summary = fmt::format(
      "{} of {} targets matched to {} seeds (total squared distance "
      "{:.2f} mm²)",
      n - match.missing_targets.size(), n, m, match.total_squared_distance_mm2);
  if (!match.missing_targets.empty()) {
    std::string ids;
    for (std::size_t i : match.missing_targets)
      ids += (ids.empty() ? "" : ", ") + std::to_string(targets[i].id);
    match.summary += fmt::format("; no seed within {:g} mm of target(s) {}", d_max, ids);
  }
  if (!match.extra_seeds.empty()) {
    match.summary += "; extra: " + seedList(match.extra_seeds) + " mm";
  }
  if (worst < n) {
    match.summary += fmt::format("; the closest alternative (target {}) is {:.1f} SD worse",
                                 match.targets[worst].target_id, match.min_margin_sd);
  }
  return match;
}

}  // namespace ignav::verification
