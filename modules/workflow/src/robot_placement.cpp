// place_robot's jobs (background_jobs.hpp): where to mount the robot, and how far a mounted one
// stands from that, on the session's structures (modules/placement does the geometry).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "ignav/deflection/bicycle_model.hpp"
#include "ignav/workflow/background_jobs.hpp"

namespace ignav::workflow {
namespace {

// The coverage is counted on a lattice of the structure's voxels: about this many samples for
// the search (each pose's full evaluation), twice as fine for the figures reported.
constexpr double kSearchSamples = 700.0;
constexpr double kMinSample_mm = 1.0;
constexpr double kMaxSample_mm = 6.0;

struct Models {
  placement::CoverageModel search, final;
};

Expected<Models> coverageModels(const std::string& structure, const PlacementScene& scene) {
  const auto& set = scene.structures.set;
  const anatomy::Structure* covered = set ? set->find(structure) : nullptr;
  if (!covered) {
    return makeError(ErrorCode::kInvalidArgument, fmt::format("'{}' is not loaded", structure));
  }
  const auto& robot = *scene.robot;
  placement::CoverageInputs in;
  in.kinematics = std::make_shared<const kinematics::Kinematics>(robot.kinematics);
  in.markers_robot_mm = robot.feature_points_mm;
  in.fle_mm = robot.config.registration.fle_mm;
  in.kind = robot.config.registration.kind;
  in.ct = scene.ct;
  in.target = std::shared_ptr<const anatomy::Structure>(set, covered);
  for (std::size_t n = 0; n < set->structures.size(); ++n) {
    const auto& role = scene.roles.at(n);
    if (role.role != anatomy::Role::kAvoid) continue;
    in.avoided.push_back({set->structures[n].name, scene.structures.fields.at(n), role.margin_mm});
  }
  if (scene.tissue) {
    // The sideways drift the tissue predicts after z_c mm, as a target's prediction gives it.
    const int travel = static_cast<int>(std::ceil(robot.kinematics.instrument().cannula_travel_mm));
    for (int z_c = 0; z_c <= travel; ++z_c) {
      double drift = 0.0;
      if (z_c > 0) {
        if (auto path = deflection::simulate(scene.tissue->needle, scene.tissue->tissue, z_c, z_c))
          drift = std::abs(path->back().y_mm);
      }
      in.drift_mm_by_z_c.push_back(drift);
    }
  }
  const double volume_mm3 = covered->mask.volume_cm3() * 1000.0;
  const double sample_mm =
      std::clamp(std::cbrt(volume_mm3 / kSearchSamples), kMinSample_mm, kMaxSample_mm);
  auto search = placement::CoverageModel::create(in, sample_mm);
  if (!search) return search.error();
  auto final = placement::CoverageModel::create(std::move(in), 0.5 * sample_mm);
  if (!final) return final.error();
  return Models{std::move(*search), std::move(*final)};
}

// "15.5 % out of reach, 8.0 % too close to 'urethra'"
std::string leftOut(const placement::Coverage& c,
                    const std::vector<placement::AvoidedStructure>& avoided) {
  std::string out;
  auto add = [&](std::size_t count, const std::string& why) {
    if (count == 0 || c.samples == 0) return;
    out += fmt::format("{}{:.1f} % {}", out.empty() ? "" : ", ",
                       100.0 * static_cast<double>(count) / static_cast<double>(c.samples), why);
  };
  add(c.unreachable, "out of reach");
  for (std::size_t n = 0; n < c.too_close.size() && n < avoided.size(); ++n)
    add(c.too_close[n], fmt::format("too close to '{}'", avoided[n].name));
  return out;
}

std::string lps(const Eigen::Vector3d& p) {
  return fmt::format("({:.1f}, {:.1f}, {:.1f}) mm LPS", p.x(), p.y(), p.z());
}

}  // namespace

PlacementScene placementScene(const Session& s) {
  return {s.robot, s.ct.volume, s.structures.loaded, s.structures.roles, s.tissue};
}

Input placeRobot(std::uint64_t job, const std::string& structure,
                 const anatomy::PlacementLimits& limits, const PlacementScene& scene,
                 const JobContext& context) {
  Input in;
  in.job = job;
  in.path = fmt::format("{} from {}", structure, limits.approach);
  in.kind = InputKind::kRobotPlacementFailed;
  auto models = coverageModels(structure, scene);
  if (!models) {
    in.error = models.error().message;
    return in;
  }
  auto placed = placement::placeRobot(models->search, models->final, limits, 3, context.progress);
  if (!placed) {
    in.error = fmt::format("'{}' from {}: {}", structure, limits.approach, placed.error().message);
    return in;
  }
  const auto& best = placed->poses.front();
  const double cm3 = models->final.inputs().target->mask.volume_cm3();
  std::string alternatives;
  for (std::size_t n = 1; n < placed->poses.size(); ++n)
    alternatives += fmt::format("{}{:.1f} %", alternatives.empty() ? "" : ", ",
                                100.0 * placed->poses[n].coverage.fraction());
  const std::string left_out = leftOut(best.coverage, models->final.inputs().avoided);
  in.summary = fmt::format(
      "robot placed for '{}' from {}: one insertion covers {:.1f} % of it ({:.1f} of {:.1f} "
      "cm³) with every clearance kept{}; entry {}, the axis {:.1f}° from the approach and {:.1f} "
      "mm from the centroid, the robot's origin {:.1f} mm outside the skin{}{} ({} poses "
      "evaluated in full)",
      structure, limits.approach, 100.0 * best.coverage.fraction(), best.coverage.fraction() * cm3,
      cm3, left_out.empty() ? "" : " (left out: " + left_out + ")", lps(best.skin.entry_lps_mm),
      best.tilt_deg, best.shift_mm, best.skin.skin_distance_mm,
      best.skin.seen ? "" : " (the CT shows no skin on the axis: its edge stands in)",
      alternatives.empty() ? "" : "; alternatives cover " + alternatives, placed->evaluations);
  in.placements = std::move(placed->poses);
  in.kind = InputKind::kRobotPlaced;
  return in;
}

Input checkPlacement(std::uint64_t job, const std::string& structure,
                     const placement::PlacedPose& proposed, const anatomy::PlacementLimits& limits,
                     const registration::Registration& registration, const PlacementScene& scene,
                     const JobContext& context) {
  Input in;
  in.job = job;
  in.path = structure;
  in.kind = InputKind::kPlacementCheckFailed;
  auto models = coverageModels(structure, scene);
  if (!models) {
    in.error = models.error().message;
    return in;
  }
  if (context.progress) context.progress(0, 1);
  const auto pose = placement::RobotPose::of(registration);
  MountedPlacement mounted;
  mounted.coverage = models->final.coverage(pose);
  mounted.skin = models->final.skinEntry(pose, limits.skin_hu);
  mounted.deviation = placement::deviation(proposed, pose, mounted.skin);
  if (context.progress) context.progress(1, 1);
  const double proposed_pct = 100.0 * proposed.coverage.fraction();
  const double mounted_pct = 100.0 * mounted.coverage.fraction();
  const auto& d = mounted.deviation;
  in.summary = fmt::format(
      "the robot is mounted {:.1f} mm ({}) and {:.1f}° (axis) from the placement proposed, {:.1f} "
      "mm {}: it covers {:.1f} % of '{}' where the proposal covers {:.1f} % ({})",
      d.entry_mm,
      mounted.skin.seen && proposed.skin.seen ? "entry on the skin" : "where the axes enter",
      d.axis_deg, std::abs(d.depth_mm), d.depth_mm >= 0.0 ? "deeper" : "shallower", mounted_pct,
      structure, proposed_pct,
      mounted_pct >= proposed_pct
          ? "nothing lost"
          : fmt::format("{:.1f} points less; left out: {}", proposed_pct - mounted_pct,
                        leftOut(mounted.coverage, models->final.inputs().avoided)));
  in.mounted = std::move(mounted);
  in.kind = InputKind::kPlacementChecked;
  return in;
}

}  // namespace ignav::workflow
