// A seed plan (seed_plan.hpp): GLPK's relaxation, then a repair and a prune judged on counts.
#include "ignav/dosimetry/seed_plan.hpp"

#include <glpk.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <tuple>

#include <fmt/format.h>

namespace ignav::dosimetry {
namespace {

// Gy of a permanent implant per (cGy h⁻¹ U⁻¹) of initial dose rate at `strength_U`.
double implantGyPerRate(const DoseRateTable& table, double strength_U) {
  return strength_U * permanentImplantDose_cGy(1.0, table.model().half_life_h) / 100.0;
}

double doseAt(const DoseRateTable& table, const Seed& seed, double gy_per_rate,
              const Eigen::Vector3d& p) {
  const Eigen::Vector3d d = p - seed.centre_lps_mm;
  const double along = d.dot(seed.axis_lps);
  const double away = std::sqrt(std::max(0.0, d.squaredNorm() - along * along));
  return gy_per_rate * table.perUnitStrength(along, away);
}

// Every dose of `seeds` at each of `points`.
std::vector<double> dosesAt(const DoseRateTable& table, const std::vector<Seed>& seeds,
                            double gy_per_rate, const std::vector<Eigen::Vector3d>& points) {
  std::vector<double> out(points.size(), 0.0);
  for (const auto& seed : seeds)
    for (std::size_t i = 0; i < points.size(); ++i)
      out[i] += doseAt(table, seed, gy_per_rate, points[i]);
  return out;
}

std::string percent(double fraction) {
  return fmt::format("{:.1f} %", 100.0 * fraction);
}

// A structure's voxels, at most `most` of them spread evenly through its list (voxel
// ⌊i · n / most⌋ for the i-th).
std::vector<Eigen::Vector3d> spread(const std::vector<Eigen::Vector3d>& voxels, std::size_t most) {
  const std::size_t n = voxels.size();
  if (n <= most) return voxels;
  std::vector<Eigen::Vector3d> out;
  out.reserve(most);
  for (std::size_t i = 0; i < most; ++i)
    out.push_back(voxels[i * n / most]);
  return out;
}

// A constraint as a count of sample points: a floor (at least `count` points get ≥ dose_Gy)
// for the target, a ceiling (at most `count` get > dose_Gy) for an organ.
struct Bound {
  std::size_t structure = 0;  // 0: the target, k: organ k - 1
  double dose_Gy = 0.0;
  bool floor = true;
  std::size_t count = 0;
};

std::size_t ceilCount(double fraction, std::size_t n) {
  const double c = std::ceil(fraction * static_cast<double>(n) - 1e-9);
  return static_cast<std::size_t>(std::clamp(c, 1.0, static_cast<double>(n)));
}

// The structures sampled, each candidate's dose at every sample point, the running sums.
class Scene {
 public:
  Scene(const SeedPlanRequest& r, std::size_t target_points, std::size_t organ_points,
        const PlanProgress& progress)
      : gy_per_rate_(implantGyPerRate(*r.table, r.strength_U)) {
    samples_.push_back(spread(r.target.voxels_lps_mm, target_points));
    for (const auto& organ : r.organs)
      samples_.push_back(spread(organ.structure.voxels_lps_mm, organ_points));
    const std::size_t j_count = r.candidates.size();
    influence_.resize(samples_.size());
    for (std::size_t s = 0; s < samples_.size(); ++s)
      influence_[s].resize(j_count * samples_[s].size());
    for (std::size_t j = 0; j < j_count; ++j) {
      if (progress && j % 32 == 0) progress(j, j_count, "dose per candidate");
      for (std::size_t s = 0; s < samples_.size(); ++s) {
        const auto& points = samples_[s];
        float* row = &influence_[s][j * points.size()];
        for (std::size_t i = 0; i < points.size(); ++i)
          row[i] = static_cast<float>(doseAt(*r.table, r.candidates[j], gy_per_rate_, points[i]));
      }
    }
    if (progress) progress(j_count, j_count, "dose per candidate");
    // The implanted seeds' dose is there before any candidate's.
    dose_.resize(samples_.size());
    for (std::size_t s = 0; s < samples_.size(); ++s)
      dose_[s] = dosesAt(*r.table, r.implanted, gy_per_rate_, samples_[s]);
    implanted_dose_ = dose_;
    chosen_.assign(j_count, false);
  }

  std::size_t points(std::size_t s) const { return samples_[s].size(); }
  const float* influence(std::size_t s, std::size_t j) const {
    return &influence_[s][j * samples_[s].size()];
  }
  const std::vector<double>& dose(std::size_t s) const { return dose_[s]; }
  bool chosen(std::size_t j) const { return chosen_[j]; }
  double implantedDose(std::size_t s, std::size_t i) const { return implanted_dose_[s][i]; }
  std::size_t chosenCount() const {
    return static_cast<std::size_t>(std::count(chosen_.begin(), chosen_.end(), true));
  }
  std::vector<std::size_t> chosenList() const {
    std::vector<std::size_t> out;
    for (std::size_t j = 0; j < chosen_.size(); ++j)
      if (chosen_[j]) out.push_back(j);
    return out;
  }

  void set(std::size_t j, bool on) {
    if (chosen_[j] == on) return;
    chosen_[j] = on;
    const double sign = on ? 1.0 : -1.0;
    for (std::size_t s = 0; s < samples_.size(); ++s) {
      const float* a = influence(s, j);
      auto& d = dose_[s];
      for (std::size_t i = 0; i < d.size(); ++i)
        d[i] += sign * a[i];
    }
  }
  void clear() {
    for (std::size_t j = 0; j < chosen_.size(); ++j)
      set(j, false);
  }

  // The points of `b` on the right side of its dose now (floor: at or above; ceiling: above).
  std::size_t counted(const Bound& b) const {
    const auto& d = dose_[b.structure];
    return static_cast<std::size_t>(std::count_if(
        d.begin(), d.end(), [&](double v) { return b.floor ? v >= b.dose_Gy : v > b.dose_Gy; }));
  }
  bool holds(const Bound& b) const {
    return b.floor ? counted(b) >= b.count : counted(b) <= b.count;
  }
  // How much of a floor's shortfall candidate j fills, in points' worth (Σ min(a, short)/dose).
  double filling(const Bound& b, std::size_t j) const {
    const auto& d = dose_[b.structure];
    const float* a = influence(b.structure, j);
    double sum = 0.0;
    for (std::size_t i = 0; i < d.size(); ++i)
      if (d[i] < b.dose_Gy) sum += std::min(static_cast<double>(a[i]), b.dose_Gy - d[i]);
    return sum / b.dose_Gy;
  }
  // How many points candidate j would move across `b`'s dose (up: j adds dose).
  std::size_t crossing(const Bound& b, std::size_t j) const {
    const auto& d = dose_[b.structure];
    const float* a = influence(b.structure, j);
    std::size_t n = 0;
    if (b.floor) {
      for (std::size_t i = 0; i < d.size(); ++i)
        n += d[i] < b.dose_Gy && d[i] + a[i] >= b.dose_Gy;
    } else {
      for (std::size_t i = 0; i < d.size(); ++i)
        n += d[i] <= b.dose_Gy && d[i] + a[i] > b.dose_Gy;
    }
    return n;
  }

 private:
  double gy_per_rate_;
  std::vector<std::vector<Eigen::Vector3d>> samples_;  // [0] target, then the organs
  std::vector<std::vector<float>> influence_;          // [structure][candidate · points + point]
  std::vector<std::vector<double>> dose_;
  std::vector<std::vector<double>> implanted_dose_;  // the implanted seeds' share of dose_
  std::vector<bool> chosen_;
};

// How much stricter than asked the sample's goals are (fractions): the sample may be kinder
// than every voxel, so each goal the whole missed is tightened by what it missed.
struct Tightening {
  double target = 0.002;  // V100 raised by it, the D90 dose by its fraction
  double organ = 0.0;     // each organ's limits lowered by its fraction
};

// The request's goals as bounds on the scene's samples.
std::vector<Bound> boundsOf(const SeedPlanRequest& r, const Scene& scene, const Tightening& t) {
  std::vector<Bound> out;
  const double rx = r.prescription_Gy;
  const std::size_t nt = scene.points(0);
  out.push_back({0, rx, true, ceilCount(std::min(1.0, r.min_v100 + t.target), nt)});
  out.push_back({0, rx * r.min_d90_percent / 100.0 * (1.0 + t.target), true, ceilCount(0.9, nt)});
  for (std::size_t k = 0; k < r.organs.size(); ++k) {
    const auto& o = r.organs[k];
    const std::size_t n = scene.points(k + 1);
    const double scale = rx / 100.0 * (1.0 - t.organ);
    if (std::isfinite(o.limits.d10_percent))
      out.push_back({k + 1, o.limits.d10_percent * scale, false, ceilCount(0.1, n) - 1});
    if (std::isfinite(o.limits.d2cc_percent)) {
      const double fraction =
          2.0 / (o.structure.voxel_cm3 * static_cast<double>(o.structure.voxels_lps_mm.size()));
      out.push_back({k + 1, o.limits.d2cc_percent * scale, false, ceilCount(fraction, n) - 1});
    }
    if (std::isfinite(o.limits.dmax_percent))
      out.push_back({k + 1, o.limits.dmax_percent * scale, false, 0});
  }
  return out;
}

// The linear relaxation (GLPK, dual simplex): minimise Σ x_j + W·(mean target shortfall) +
// W·(mean organ excess), x_j in 0-1, on a subsample of the scene's points, doses in units of
// the prescription. Returns each candidate's weight (zeros when GLPK fails).
std::vector<double> relax(const SeedPlanRequest& r, const Scene& scene, std::size_t target_rows,
                          std::size_t organ_rows) {
  constexpr double kPenalty = 1000.0;  // a 1 % mean shortfall costs 10 seeds
  const std::size_t nj = r.candidates.size();
  const double rx = r.prescription_Gy;
  struct Row {
    std::size_t structure, point;
    double limit;  // in prescriptions; floor for the target, ceiling for organs
  };
  std::vector<Row> rows;
  {
    const std::size_t n = scene.points(0), step = std::max<std::size_t>(1, n / target_rows);
    for (std::size_t i = 0; i < n; i += step)
      rows.push_back({0, i, r.min_d90_percent / 100.0});
  }
  const std::size_t target_count = rows.size();
  for (std::size_t k = 0; k < r.organs.size(); ++k) {
    const auto& l = r.organs[k].limits;
    double limit = std::numeric_limits<double>::infinity();
    for (double v : {l.d10_percent, l.d2cc_percent, l.dmax_percent})
      if (std::isfinite(v)) limit = std::min(limit, v / 100.0);
    if (!std::isfinite(limit)) continue;
    // Only points every candidate together could push over the limit need a row.
    std::vector<std::size_t> bind;
    for (std::size_t i = 0; i < scene.points(k + 1); ++i) {
      double all = 0.0;
      for (std::size_t j = 0; j < nj; ++j)
        all += scene.influence(k + 1, j)[i];
      all += scene.implantedDose(k + 1, i);
      if (all / rx > limit) bind.push_back(i);
    }
    const std::size_t step = std::max<std::size_t>(1, bind.size() / organ_rows);
    for (std::size_t m = 0; m < bind.size(); m += step)
      rows.push_back({k + 1, bind[m], limit});
  }
  const std::size_t organ_count = rows.size() - target_count;

  glp_prob* lp = glp_create_prob();
  glp_set_obj_dir(lp, GLP_MIN);
  const int cols = static_cast<int>(nj + rows.size());  // x, then one slack per row
  glp_add_cols(lp, cols);
  for (std::size_t j = 0; j < nj; ++j) {
    glp_set_col_bnds(lp, static_cast<int>(j) + 1, GLP_DB, 0.0, 1.0);
    glp_set_obj_coef(lp, static_cast<int>(j) + 1, 1.0);
  }
  glp_add_rows(lp, static_cast<int>(rows.size()));
  std::vector<int> ia{0}, ja{0};
  std::vector<double> ar{0.0};
  for (std::size_t m = 0; m < rows.size(); ++m) {
    const Row& row = rows[m];
    const int rm = static_cast<int>(m) + 1, slack = static_cast<int>(nj + m) + 1;
    const bool target = row.structure == 0;
    // What the implanted seeds give is there already.
    const double room = row.limit - scene.implantedDose(row.structure, row.point) / rx;
    glp_set_row_bnds(lp, rm, target ? GLP_LO : GLP_UP, room, room);
    glp_set_col_bnds(lp, slack, target ? GLP_DB : GLP_LO, 0.0, row.limit);
    glp_set_obj_coef(lp, slack,
                     kPenalty / static_cast<double>(target ? target_count : organ_count));
    for (std::size_t j = 0; j < nj; ++j) {
      const double a = scene.influence(row.structure, j)[row.point] / rx;
      if (a < 1e-4) continue;
      ia.push_back(rm);
      ja.push_back(static_cast<int>(j) + 1);
      ar.push_back(a);
    }
    ia.push_back(rm);
    ja.push_back(slack);
    ar.push_back(target ? 1.0 : -1.0);
  }
  glp_load_matrix(lp, static_cast<int>(ar.size()) - 1, ia.data(), ja.data(), ar.data());
  // GLPK's terminal output (per thread) stays off: its scaling reports went to stdout.
  const int terminal = glp_term_out(GLP_OFF);
  glp_scale_prob(lp, GLP_SF_AUTO);
  glp_smcp parm;
  glp_init_smcp(&parm);
  parm.msg_lev = GLP_MSG_OFF;
  parm.meth = GLP_DUALP;  // all at zero is dual feasible: the objective's costs are ≥ 0
  parm.tm_lim = 20000;
  std::vector<double> weight(nj, 0.0);
  if (glp_simplex(lp, &parm) == 0)
    for (std::size_t j = 0; j < nj; ++j)
      weight[j] = glp_get_col_prim(lp, static_cast<int>(j) + 1);
  glp_delete_prob(lp);
  glp_term_out(terminal);
  return weight;
}

// The chosen seed giving the most dose to `b`'s points above `from_Gy`; none: the candidates'
// count.
std::size_t hottestContributor(const Scene& scene, const Bound& b, double from_Gy,
                               std::size_t candidates) {
  const auto& d = scene.dose(b.structure);
  double most = 0.0;
  std::size_t worst = candidates;
  for (std::size_t j = 0; j < candidates; ++j) {
    if (!scene.chosen(j)) continue;
    const float* a = scene.influence(b.structure, j);
    double sum = 0.0;
    for (std::size_t i = 0; i < d.size(); ++i)
      if (d[i] > from_Gy) sum += a[i];
    if (sum > most) most = sum, worst = j;
  }
  return worst;
}

// Adds and drops candidates until every bound holds (true) or nothing more helps (false).
// Dropped candidates are not tried again.
bool repair(Scene& scene, const std::vector<Bound>& bounds, std::vector<bool>& banned,
            const PlanProgress& progress) {
  const std::size_t nj = banned.size();
  const std::size_t limit = 2 * nj + 10;  // each candidate added once and dropped once at most
  auto drop = [&](std::size_t j) {
    scene.set(j, false);
    banned[j] = true;
  };
  for (std::size_t step = 0; step < limit; ++step) {
    if (progress) progress(step, limit, "repair");
    const Bound* broken_organ = nullptr;
    bool target_short = false;
    for (const auto& b : bounds) {
      if (scene.holds(b)) continue;
      if (b.floor)
        target_short = true;
      else if (!broken_organ)
        broken_organ = &b;
    }
    if (!broken_organ && !target_short) return true;
    if (broken_organ) {
      const std::size_t worst = hottestContributor(scene, *broken_organ, broken_organ->dose_Gy, nj);
      if (worst == nj) return false;
      drop(worst);
      continue;
    }
    // Add the candidate that newly covers the most of the target (ties: that fills the most of
    // its shortfall), keeping every organ's limit.
    std::size_t best = nj;
    double best_score = 0.0;
    for (std::size_t j = 0; j < nj; ++j) {
      if (scene.chosen(j) || banned[j]) continue;
      bool keeps = true;
      double score = 0.0;
      for (const auto& b : bounds) {
        if (b.floor) {
          score += static_cast<double>(scene.crossing(b, j)) + 0.05 * scene.filling(b, j);
        } else if (scene.counted(b) + scene.crossing(b, j) > b.count) {
          keeps = false;
          break;
        }
      }
      if (keeps && score > best_score) best_score = score, best = j;
    }
    if (best != nj) {
      scene.set(best, true);
      continue;
    }
    // Every addition would break an organ's limit: make room by dropping the seed that gives
    // the most to the tightest organ's points near its limit.
    const Bound* tightest = nullptr;
    for (const auto& b : bounds)
      if (!b.floor &&
          (!tightest || b.count - std::min(b.count, scene.counted(b)) <
                            tightest->count - std::min(tightest->count, scene.counted(*tightest))))
        tightest = &b;
    if (!tightest) return false;
    const std::size_t worst = hottestContributor(scene, *tightest, 0.8 * tightest->dose_Gy, nj);
    if (worst == nj) return false;
    drop(worst);
  }
  return false;
}

// Drops every seed the bounds do without, the least useful (lowest relaxed weight) first.
void prune(Scene& scene, const std::vector<Bound>& bounds, const std::vector<double>& weight) {
  auto order = scene.chosenList();
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return weight[a] < weight[b]; });
  for (const std::size_t j : order) {
    scene.set(j, false);
    const bool ok = std::all_of(bounds.begin(), bounds.end(),
                                [&](const Bound& b) { return !b.floor || scene.holds(b); });
    if (!ok) scene.set(j, true);
  }
}

std::vector<Seed> seedsOf(const SeedPlanRequest& r, const std::vector<std::size_t>& chosen) {
  std::vector<Seed> out;
  for (const std::size_t j : chosen)
    out.push_back(r.candidates[j]);
  return out;
}

Error infeasible(const SeedPlanRequest& r, const PlanEvaluation& best, std::size_t seeds) {
  return makeError(
      ErrorCode::kInvalidArgument,
      fmt::format("no seed plan among the {} candidates meets {}; the best of {} seeds of {:g} U "
                  "reached {}",
                  r.candidates.size(), fmt::join(best.unmet, ", "), seeds, r.strength_U,
                  best.describe()),
      "infeasible_plan");
}

constexpr std::size_t kTargetSample = 12000, kOrganSample = 4000;

}  // namespace

namespace {

// Every seed's centre finite and its axis a unit vector (`what` names them in the error).
Status seedsFit(const std::vector<Seed>& seeds, const char* what) {
  for (std::size_t j = 0; j < seeds.size(); ++j) {
    const Seed& c = seeds[j];
    if (!c.centre_lps_mm.allFinite() || !c.axis_lps.allFinite() ||
        std::abs(c.axis_lps.norm() - 1.0) > 1e-6) {
      return makeError(
          ErrorCode::kInvalidArgument,
          fmt::format("{} {}: its centre or axis (a unit vector) is not finite", what, j),
          "bad_candidate");
    }
  }
  return Ok{};
}

// What a dose needs of a request (validate without the candidates): evaluating given seeds.
Status validateDose(const SeedPlanRequest& r) {
  auto bad = [](std::string message, const char* reason) -> Status {
    return makeError(ErrorCode::kInvalidArgument, std::move(message), reason);
  };
  if (!r.table) return bad("seed plan: no seed model", "unknown_seed_model");
  if (!std::isfinite(r.strength_U) || r.strength_U < kMinSeedStrength_U ||
      r.strength_U > kMaxSeedStrength_U)
    return bad(fmt::format("seed strength {} U is outside {:g}-{:g} U", r.strength_U,
                           kMinSeedStrength_U, kMaxSeedStrength_U),
               "bad_strength");
  if (!std::isfinite(r.prescription_Gy) || r.prescription_Gy <= 0.0)
    return bad(fmt::format("prescription {} Gy: must be a positive dose", r.prescription_Gy),
               "bad_prescription");
  if (!(r.min_v100 > 0.0 && r.min_v100 <= 1.0) ||
      !(r.min_d90_percent > 0.0 && r.min_d90_percent <= 300.0) || r.max_seeds == 0)
    return bad(fmt::format("seed plan goals: V100 {} (0-1], D90 {} % (0-300], at most {} seeds",
                           r.min_v100, r.min_d90_percent, r.max_seeds),
               "bad_goal");
  auto structure = [&](const DoseStructure& s, const char* what) -> Status {
    if (s.voxels_lps_mm.empty() || !(s.voxel_cm3 > 0.0) || !std::isfinite(s.voxel_cm3))
      return bad(fmt::format("{} '{}' has no voxels", what, s.name), "empty_structure");
    for (const auto& p : s.voxels_lps_mm)
      if (!p.allFinite())
        return bad(fmt::format("{} '{}' has a voxel at a non-finite point", what, s.name),
                   "empty_structure");
    return Ok{};
  };
  if (auto ok = structure(r.target, "target"); !ok.ok()) return ok;
  for (const auto& o : r.organs) {
    if (auto ok = structure(o.structure, "organ"); !ok.ok()) return ok;
    for (double v : {o.limits.d10_percent, o.limits.d2cc_percent, o.limits.dmax_percent})
      if (!std::isnan(v) && !(v > 0.0 && std::isfinite(v)))
        return bad(fmt::format("organ '{}': a dose limit of {} % is no limit", o.structure.name, v),
                   "bad_limit");
  }
  return seedsFit(r.implanted, "implanted seed");
}

}  // namespace

Status validate(const SeedPlanRequest& r) {
  if (auto ok = validateDose(r); !ok.ok()) return ok;
  if (r.candidates.empty()) {
    return makeError(ErrorCode::kInvalidArgument,
                     "seed plan: no candidate positions (none reachable with every clearance kept)",
                     "no_candidates");
  }
  return seedsFit(r.candidates, "candidate");
}

std::string PlanEvaluation::describe() const {
  std::string out = fmt::format("V100 {}, D90 {:.1f} %", percent(target.v100), target.d90_percent);
  for (const auto& o : organs) {
    const auto& m = o.metrics;
    out += fmt::format("; {} D10 {:.1f} %, D2cc {:.1f} Gy, Dmax {:.0f} %", o.name, m.d10_percent,
                       m.d2cc_Gy, m.dmax_percent);
  }
  return out;
}

Expected<PlanEvaluation> evaluatePlan(const SeedPlanRequest& r, const std::vector<Seed>& seeds) {
  if (auto ok = validateDose(r); !ok.ok()) return ok.error();
  if (auto ok = seedsFit(seeds, "seed"); !ok.ok()) return ok.error();
  const double g = implantGyPerRate(*r.table, r.strength_U), rx = r.prescription_Gy;
  std::vector<Seed> all = seeds;
  all.insert(all.end(), r.implanted.begin(), r.implanted.end());
  PlanEvaluation e;
  auto target = DoseVolumeHistogram::of(dosesAt(*r.table, all, g, r.target.voxels_lps_mm),
                                        r.target.voxel_cm3);
  if (!target.ok()) return target.error();
  auto curve = [rx](const std::string& name, const DoseVolumeHistogram& h) {
    auto cumulative = h.cumulative(kCurveBin_Gy);
    cumulative.resize(std::min(cumulative.size(), static_cast<std::size_t>(3.0 * rx) + 2));
    return StructureCurve{name, std::move(cumulative)};
  };
  e.curves.push_back(curve(r.target.name, *target));
  e.target = targetMetrics(*target, rx);
  e.target_cm3 = target->volume_cm3();
  if (e.target.v100 < r.min_v100)
    e.unmet.push_back(
        fmt::format("{} V100 {} < {}", r.target.name, percent(e.target.v100), percent(r.min_v100)));
  if (e.target.d90_percent < r.min_d90_percent)
    e.unmet.push_back(fmt::format("{} D90 {:.1f} % < {:g} %", r.target.name, e.target.d90_percent,
                                  r.min_d90_percent));
  for (const auto& o : r.organs) {
    auto h = DoseVolumeHistogram::of(dosesAt(*r.table, all, g, o.structure.voxels_lps_mm),
                                     o.structure.voxel_cm3);
    if (!h.ok()) return h.error();
    e.curves.push_back(curve(o.structure.name, *h));
    OrganResult result{o.structure.name, organMetrics(*h, rx), o.limits};
    const auto& m = result.metrics;
    const double d2cc_percent = 100.0 * m.d2cc_Gy / rx;
    auto over = [&](const char* what, double value, double limit) {
      if (value > limit)  // NaN limits never hold a value back
        e.unmet.push_back(
            fmt::format("{} {} {:.1f} % > {:g} %", o.structure.name, what, value, limit));
    };
    over("D10", m.d10_percent, o.limits.d10_percent);
    over("D2cc", d2cc_percent, o.limits.d2cc_percent);
    over("Dmax", m.dmax_percent, o.limits.dmax_percent);
    e.organs.push_back(std::move(result));
  }
  return e;
}

Expected<SeedPlan> planSeeds(const SeedPlanRequest& asked, const PlanProgress& progress) {
  if (auto ok = validate(asked); !ok.ok()) return ok.error();
  SeedPlan plan;
  SeedPlanRequest r = asked;
  if (!r.implanted.empty()) {
    // What the implanted seeds already give cannot be taken back.
    const auto now = evaluatePlan(r, {});
    if (!now.ok()) return now.error();
    for (std::size_t k = 0; k < r.organs.size(); ++k) {
      auto& limits = r.organs[k].limits;
      const auto& m = now->organs[k].metrics;
      const double d2cc_percent = 100.0 * m.d2cc_Gy / r.prescription_Gy;
      for (auto [limit, value, what] :
           {std::make_tuple(&limits.d10_percent, m.d10_percent, "D10"),
            std::make_tuple(&limits.d2cc_percent, d2cc_percent, "D2cc"),
            std::make_tuple(&limits.dmax_percent, m.dmax_percent, "Dmax")}) {
        if (!(value > *limit)) continue;  // NaN limits hold nothing back
        *limit = value + kReplanRise_percent;
        plan.raised_limits.push_back(
            fmt::format("{} {} {:.1f} % delivered already, held to {:.1f} %",
                        r.organs[k].structure.name, what, value, *limit));
      }
    }
  }
  Scene scene(r, kTargetSample, kOrganSample, progress);
  if (progress) progress(0, 1, "linear programme");
  const std::vector<double> weight = relax(r, scene, 1200, 400);
  if (progress) progress(1, 1, "linear programme");
  plan.relaxed_seeds = std::accumulate(weight.begin(), weight.end(), 0.0);

  // Rounded: the candidates the relaxation weighs most, as many as its weights add up to.
  std::vector<std::size_t> order(r.candidates.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return weight[a] > weight[b]; });
  const auto rounded = static_cast<std::size_t>(std::ceil(plan.relaxed_seeds - 1e-6));
  for (std::size_t m = 0; m < std::min(rounded, order.size()); ++m)
    if (weight[order[m]] > 1e-6) scene.set(order[m], true);

  // Repaired and pruned on the sample, judged on every voxel; what the whole missed is
  // tightened on the sample and repaired again.
  std::vector<bool> banned(r.candidates.size(), false);
  Tightening tighten;
  bool found = false;
  for (int round = 0; round < 6; ++round) {
    const auto bounds = boundsOf(r, scene, tighten);
    const bool held = repair(scene, bounds, banned, progress);
    if (held) prune(scene, bounds, weight);
    if (progress) progress(0, 1, "every voxel");
    auto judged = evaluatePlan(r, seedsOf(r, scene.chosenList()));
    if (progress) progress(1, 1, "every voxel");
    if (!judged.ok()) return judged.error();
    if (judged->met()) {
      plan.chosen = scene.chosenList();
      plan.evaluation = std::move(*judged);
      found = true;
      break;
    }
    if (!held) return infeasible(r, *judged, scene.chosenCount());
    const auto& m = judged->target;
    const double short_by =
        std::max(r.min_v100 - m.v100, (r.min_d90_percent - m.d90_percent) / r.min_d90_percent);
    if (short_by > 0.0) tighten.target += std::max(0.002, short_by);
    const std::size_t target_misses =
        (m.v100 < r.min_v100 ? 1u : 0u) + (m.d90_percent < r.min_d90_percent ? 1u : 0u);
    if (judged->unmet.size() > target_misses) tighten.organ += 0.005;  // an organ's limit too
  }
  if (!found) {
    auto judged = evaluatePlan(r, seedsOf(r, scene.chosenList()));
    return infeasible(r, *judged, scene.chosenCount());
  }
  if (plan.chosen.size() > r.max_seeds)
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("the plan needs {} seeds of {:g} U, more than the {} a plan "
                                 "takes; stronger seeds need fewer",
                                 plan.chosen.size(), r.strength_U, r.max_seeds),
                     "too_many_seeds");
  return plan;
}

Expected<UniformLoading> uniformLoading(const SeedPlanRequest& r) {
  if (auto ok = validate(r); !ok.ok()) return ok.error();
  Scene scene(r, kTargetSample, kOrganSample, {});
  std::vector<Bound> goals;
  for (const auto& b : boundsOf(r, scene, Tightening{0.0, 0.0}))
    if (b.floor) goals.push_back(b);
  for (double spacing = 20.0; spacing > 0.0; spacing -= 0.5) {
    scene.clear();
    std::vector<std::size_t> picked;
    for (std::size_t j = 0; j < r.candidates.size(); ++j) {
      const auto& c = r.candidates[j].centre_lps_mm;
      const bool apart = std::all_of(picked.begin(), picked.end(), [&](std::size_t p) {
        return (r.candidates[p].centre_lps_mm - c).norm() >= spacing - 1e-9;
      });
      if (!apart) continue;
      picked.push_back(j);
      scene.set(j, true);
    }
    if (!std::all_of(goals.begin(), goals.end(), [&](const Bound& b) { return scene.holds(b); }))
      continue;
    auto judged = evaluatePlan(r, seedsOf(r, picked));
    if (!judged.ok()) return judged.error();
    const bool covers =
        judged->target.v100 >= r.min_v100 && judged->target.d90_percent >= r.min_d90_percent;
    if (covers) return UniformLoading{spacing, picked, std::move(*judged)};
  }
  auto all = evaluatePlan(r, r.candidates);
  if (!all.ok()) return all.error();
  return infeasible(r, *all, r.candidates.size());
}

Expected<std::vector<ColdSpot>> coldSpots(const SeedPlanRequest& r, const std::vector<Seed>& seeds,
                                          double min_cm3) {
  if (auto ok = validateDose(r); !ok.ok()) return ok.error();
  if (auto ok = seedsFit(seeds, "seed"); !ok.ok()) return ok.error();
  std::vector<Seed> all = seeds;
  all.insert(all.end(), r.implanted.begin(), r.implanted.end());
  const auto& voxels = r.target.voxels_lps_mm;
  const auto dose = dosesAt(*r.table, all, implantGyPerRate(*r.table, r.strength_U), voxels);
  // Cold voxels hashed by cells of 1.5 voxel sides: neighbours lie in the 27 cells around.
  const double side_mm = 10.0 * std::cbrt(r.target.voxel_cm3), cell_mm = 1.5 * side_mm;
  using Key = std::array<long, 3>;
  auto keyOf = [&](const Eigen::Vector3d& p) {
    return Key{std::lround(std::floor(p.x() / cell_mm)), std::lround(std::floor(p.y() / cell_mm)),
               std::lround(std::floor(p.z() / cell_mm))};
  };
  std::map<Key, std::vector<std::size_t>> cells;
  for (std::size_t i = 0; i < voxels.size(); ++i)
    if (dose[i] < r.prescription_Gy) cells[keyOf(voxels[i])].push_back(i);
  std::vector<bool> seen(voxels.size(), false);
  std::vector<ColdSpot> out;
  for (const auto& [key, members] : cells) {
    for (const std::size_t start : members) {
      if (seen[start]) continue;
      // One region: a flood through cold neighbours.
      seen[start] = true;
      std::vector<std::size_t> stack{start}, region;
      while (!stack.empty()) {
        const std::size_t i = stack.back();
        stack.pop_back();
        region.push_back(i);
        const Key k = keyOf(voxels[i]);
        for (long dx = -1; dx <= 1; ++dx)
          for (long dy = -1; dy <= 1; ++dy)
            for (long dz = -1; dz <= 1; ++dz) {
              const auto near = cells.find({k[0] + dx, k[1] + dy, k[2] + dz});
              if (near == cells.end()) continue;
              for (const std::size_t n : near->second)
                if (!seen[n] && (voxels[n] - voxels[i]).norm() <= cell_mm) {
                  seen[n] = true;
                  stack.push_back(n);
                }
            }
      }
      ColdSpot spot;
      spot.min_dose_Gy = std::numeric_limits<double>::infinity();
      for (const std::size_t i : region) {
        spot.centroid_lps_mm += voxels[i];
        spot.min_dose_Gy = std::min(spot.min_dose_Gy, dose[i]);
      }
      spot.centroid_lps_mm /= static_cast<double>(region.size());
      spot.volume_cm3 = r.target.voxel_cm3 * static_cast<double>(region.size());
      if (spot.volume_cm3 >= min_cm3) out.push_back(spot);
    }
  }
  std::sort(out.begin(), out.end(),
            [](const ColdSpot& a, const ColdSpot& b) { return a.volume_cm3 > b.volume_cm3; });
  return out;
}

}  // namespace ignav::dosimetry
