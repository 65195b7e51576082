// propose_targets' job (background_jobs.hpp): a lattice through a structure, each point judged
// as a target would be, the ones the plan may take ordered as it would visit them.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <optional>

#include "ignav/workflow/background_jobs.hpp"
#include "motion.hpp"
#include "proposal_lattice.hpp"
#include "session_rules.hpp"

namespace ignav::workflow {

ProposalStart startProposal(std::uint64_t job, const std::string& structure, double spacing_mm,
                            const Session& s) {
  ProposalStart start;
  start.failed.job = job;
  start.failed.path = fmt::format("{} {:g}", structure, spacing_mm);
  start.failed.kind = InputKind::kTargetProposalFailed;
  const auto* set = s.structures.loaded.set.get();
  start.structure = set && s.registration ? set->find(structure) : nullptr;
  if (!start.structure)
    start.failed.error = fmt::format("'{}' is not loaded, or the CT is not registered", structure);
  return start;
}

std::optional<std::vector<Eigen::Vector3d>> latticeIn(const anatomy::Mask& mask,
                                                      const registration::Registration& reg,
                                                      double spacing_mm) {
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  std::size_t inside = 0;
  const auto& d = mask.geometry.dims;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i)
        if (mask.inside[mask.index(i, j, k)]) {
          centroid += mask.geometry.toLps(Eigen::Vector3d(i, j, k));
          ++inside;
        }
  centroid /= static_cast<double>(std::max<std::size_t>(inside, 1));
  const Eigen::Vector3d centre_robot = reg.toRobot(centroid);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& corner : mask.corners(0.5)) {
    const Eigen::Vector3d r = reg.toRobot(corner);
    lo = lo.cwiseMin(r);
    hi = hi.cwiseMax(r);
  }
  std::array<int, 3> from{}, to{};
  for (int a = 0; a < 3; ++a) {
    from[static_cast<std::size_t>(a)] =
        static_cast<int>(std::ceil((lo[a] - centre_robot[a]) / spacing_mm));
    to[static_cast<std::size_t>(a)] =
        static_cast<int>(std::floor((hi[a] - centre_robot[a]) / spacing_mm));
  }
  std::vector<Eigen::Vector3d> points;
  for (int c = from[2]; c <= to[2]; ++c)
    for (int b = from[1]; b <= to[1]; ++b)
      for (int a = from[0]; a <= to[0]; ++a) {
        const Eigen::Vector3d lps =
            reg.toImage(centre_robot + spacing_mm * Eigen::Vector3d(a, b, c));
        if (!mask.insideNearest(mask.geometry.toIjk(lps))) continue;
        if (points.size() == kMaxProposalCandidates) return std::nullopt;
        points.push_back(lps);
      }
  return points;
}

Judged judge(const Session& s, const std::vector<Eigen::Vector3d>& candidates,
             const std::function<void(std::size_t, std::size_t)>& progress) {
  Judged out;
  std::size_t unreachable = 0, outside_ct = 0, refused_aim = 0;
  std::map<std::string, std::size_t> too_close;  // by the first structure named
  for (std::size_t n = 0; n < candidates.size(); ++n) {
    if (progress && n % 16 == 0) progress(n, candidates.size());
    Target t;
    t.id = static_cast<std::uint32_t>(out.kept.size() + 1);
    t.lps_mm = candidates[n];
    detail::evaluate(s, t);  // exactly as a target there: reach, aim, path, clearance
    const std::string status = t.status();
    if (status == "planned") {
      out.kept.push_back(std::move(t));
    } else if (status == "too_close") {
      for (const auto& c : t.clearances)
        if (c.tooClose()) {
          ++too_close[c.structure];
          break;
        }
    } else if (status == "outside_volume") {
      ++outside_ct;
    } else if (t.solution.reachable()) {
      ++refused_aim;
    } else {
      ++unreachable;
    }
  }
  if (progress) progress(candidates.size(), candidates.size());
  auto leave = [&](std::size_t count, const std::string& why) {
    if (count) out.left_out += fmt::format("{}{} {}", out.left_out.empty() ? "" : ", ", count, why);
  };
  leave(unreachable, "out of the needle's reach");
  for (const auto& [name, count] : too_close)
    leave(count, fmt::format("too close to '{}'", name));
  leave(refused_aim, "whose aim the tissue model refuses");
  leave(outside_ct, "outside the CT");
  return out;
}

VisitOrder visitOrder(const Session& s, const std::vector<Target>& targets) {
  std::vector<planning::PlannedTarget> planned;
  for (const auto& t : targets)
    planned.push_back({t.id, t.commandedJoints()});
  const auto ordering =
      planning::orderTargets(planned, detail::currentJoints(*s.robot, s.position), s.policy.limits);
  VisitOrder out;
  for (const std::size_t n : ordering.order)
    out.points.push_back(targets[n].lps_mm);
  out.rotation_rad = ordering.total_rotation_rad;
  return out;
}

namespace {

// The finest spacing, in half millimetres, whose lattice keeps no more targets than `room`:
// searched from the cube-root estimate (a lattice's points go as the cube of its spacing), each
// spacing tried judged in full (a few tries at most). "" when none is found.
std::string fittingSpacing(const Session& s, const anatomy::Mask& mask, double spacing_mm,
                           std::size_t kept, std::size_t room) {
  if (room == 0) return "; remove targets first";
  const auto& reg = *s.registration;
  auto keeps = [&](double spacing) -> std::optional<std::size_t> {
    const auto points = latticeIn(mask, reg, spacing);
    if (!points) return std::nullopt;
    return judge(s, *points, {}).kept.size();
  };
  const double estimate = std::cbrt(static_cast<double>(kept) / static_cast<double>(room));
  double spacing = std::max(spacing_mm + 0.5, std::floor(2.0 * spacing_mm * estimate) / 2.0);
  std::optional<double> fits;
  for (int tries = 0; tries < 8 && spacing <= kMaxProposalSpacing_mm; ++tries) {
    const auto n = keeps(spacing);
    if (n && *n <= room) {
      fits = spacing;
      if (spacing - 0.5 <= spacing_mm) break;
      spacing -= 0.5;  // a finer one may fit too
    } else {
      if (fits) break;  // the one above was the finest
      spacing += 0.5;
    }
  }
  return fits ? fmt::format("; a spacing of {:g} mm fits", *fits) : "";
}

}  // namespace

Input proposeTargets(std::uint64_t job, const std::string& structure, double spacing_mm,
                     const std::shared_ptr<const Session>& snapshot, const JobContext& context) {
  const Session& s = *snapshot;
  auto [in, filled] = startProposal(job, structure, spacing_mm, s);
  if (!filled) return in;
  const auto& reg = *s.registration;
  const anatomy::Mask& mask = filled->mask;

  const auto candidates = latticeIn(mask, reg, spacing_mm);
  if (!candidates) {
    in.error = fmt::format(
        "a {:g} mm lattice puts more than {} points in '{}' ({:.1f} cm³): too many to try; a "
        "coarser spacing",
        spacing_mm, kMaxProposalCandidates, filled->name, mask.volume_cm3());
    return in;
  }

  const std::size_t room = s.policy.limits.max_targets > s.targets.size()
                               ? s.policy.limits.max_targets - s.targets.size()
                               : 0;
  const auto report = [&](std::size_t done, std::size_t total) {
    if (context.progress) context.progress(done, total);
  };
  const Judged judged = judge(s, *candidates, report);
  const std::string lattice =
      fmt::format("of the {} lattice points {:g} mm apart in '{}' ({:.1f} cm³)", candidates->size(),
                  spacing_mm, filled->name, mask.volume_cm3());
  if (judged.kept.empty()) {
    in.error = fmt::format("none {} is reachable with every clearance kept{}", lattice,
                           judged.left_out.empty() ? "" : ": " + judged.left_out);
    return in;
  }
  if (judged.kept.size() > room) {
    in.error = fmt::format(
        "{} {} are reachable and clear, more than the {} targets the plan can still take "
        "(planning.max_targets {}, {} planned){}",
        judged.kept.size(), lattice, room, s.policy.limits.max_targets, s.targets.size(),
        fittingSpacing(s, mask, spacing_mm, judged.kept.size(), room));
    return in;
  }
  const auto& kept = judged.kept;
  const std::string left_out = judged.left_out;

  const VisitOrder ordering = visitOrder(s, kept);
  in.points = ordering.points;
  in.summary = fmt::format(
      "{} targets proposed: {} {} are reachable with every clearance kept{}; in the order listed "
      "the cannula turns {:.1f}° in all",
      kept.size(), kept.size() == candidates->size() ? "all" : std::to_string(kept.size()), lattice,
      left_out.empty() ? "" : " (left out: " + left_out + ")",
      ordering.rotation_rad * 180.0 / M_PI);
  in.kind = InputKind::kTargetsProposed;
  return in;
}

}  // namespace ignav::workflow
