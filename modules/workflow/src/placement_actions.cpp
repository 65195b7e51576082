// The rows' actions for where to mount the robot (issue 41, part 4; actions.hpp): asking for a
// placement, taking its outcome, and measuring a mounted robot against it after a registration.
#include <sstream>

#include <fmt/format.h>

#include "actions.hpp"
#include "ignav/workflow/background_jobs.hpp"
#include "session_rules.hpp"

namespace ignav::workflow::detail {

void checkMountedRobot(Session& s, Effects& e) {
  auto& p = s.robot_placement;
  p.mounted.reset();
  p.mounted_message.clear();
  p.checking = 0;
  if (p.status == "placed" && s.registration) {
    p.checking = s.revision + 1;  // this step's
    p.mounted_message = "measuring the mounted robot against the placement proposed";
    e.start_jobs.push_back(JobKind::kPlacementCheck);
  }
  e.structures_changed = true;
}

Refusal startRobotPlacement(Session& s, const Input& in, ActionOutput& out) {
  const auto& st = s.structures;
  if (!st.loaded.set) {
    return Rejection{ReplyCode::kNoStructures, "no structures are loaded (load_structures)"};
  }
  auto& p = s.robot_placement;
  if (p.placing != 0) {
    return Rejection{ReplyCode::kBusy, fmt::format("the robot is being placed (#{})", p.placing)};
  }
  // STRUCTURE [from SIDE], the name possibly of several words.
  std::vector<std::string> words;
  std::istringstream text(in.path);
  for (std::string w; text >> w;)
    words.push_back(w);
  anatomy::PlacementLimits limits = s.site ? s.site->placement : anatomy::PlacementLimits{};
  if (words.size() >= 2 && anatomy::namesMatch(words[words.size() - 2], "from")) {
    const auto direction = anatomy::insertionFrom(words.back());
    if (!direction) {
      return Rejection{ReplyCode::kBadApproach,
                       fmt::format("'{}': a needle cannot come from '{}' (inferior, superior, "
                                   "anterior, posterior, left, right)",
                                   in.path, words.back())};
    }
    limits.approach = words.back();
    limits.insertion_lps = *direction;
    words.resize(words.size() - 2);
  }
  std::string name;
  for (const auto& w : words)
    name += (name.empty() ? "" : " ") + w;
  const auto* structure = st.loaded.set->find(name);
  if (!structure) {
    std::string loaded;
    for (const auto& one : st.loaded.set->structures)
      loaded += (loaded.empty() ? "" : ", ") + one.name;
    return Rejection{
        ReplyCode::kUnknownStructure,
        fmt::format("no structure '{}' (loaded: {}; STRUCTURE [from SIDE])", name, loaded)};
  }
  p = {};
  p.placing = s.revision + 1;  // this step's
  p.status = "placing";
  p.structure = structure->name;
  p.limits = limits;
  p.structure_cm3 = structure->mask.volume_cm3();
  p.message = fmt::format(
      "placing the robot to cover '{}' from {} (tilt ≤ {:g}°, axis ≤ {:g} mm from its centroid, "
      "origin ≥ {:g} mm outside the skin)",
      structure->name, limits.approach, limits.max_tilt_deg, limits.max_shift_mm,
      limits.min_skin_distance_mm);
  out.effects.start_jobs.push_back(JobKind::kRobotPlacement);
  out.effects.structures_changed = true;
  out.note = fmt::format(
      "robot placement #{} started: StructuresState shows the poses found, the best first, or "
      "why none",
      p.placing);
  return std::nullopt;
}

namespace {

// The placement's outcome: its poses (none when it failed) and what it said. A registration
// already there measures the robot against a placement at once.
Refusal endPlacement(Session& s, const char* status, const std::string& message,
                     std::vector<placement::PlacedPose> poses, ActionOutput& out) {
  auto& p = s.robot_placement;
  p.placing = 0;
  p.status = status;
  p.message = message;
  p.poses = std::move(poses);
  out.note = message;
  checkMountedRobot(s, out.effects);
  return std::nullopt;
}

// The placement check's outcome: the mounted robot measured, or why not.
Refusal endCheck(Session& s, std::optional<MountedPlacement> mounted, const std::string& message,
                 ActionOutput& out) {
  auto& p = s.robot_placement;
  p.checking = 0;
  p.mounted = std::move(mounted);
  p.mounted_message = message;
  out.effects.structures_changed = true;
  out.note = message;
  return std::nullopt;
}

}  // namespace

Refusal adoptRobotPlacement(Session& s, const Input& in, ActionOutput& out) {
  return endPlacement(s, "placed", in.summary, in.placements, out);
}

Refusal noteRobotPlacementFailure(Session& s, const Input& in, ActionOutput& out) {
  return endPlacement(s, "failed", in.error, {}, out);
}

Refusal adoptPlacementCheck(Session& s, const Input& in, ActionOutput& out) {
  return endCheck(s, in.mounted, in.summary, out);
}

Refusal notePlacementCheckFailure(Session& s, const Input& in, ActionOutput& out) {
  return endCheck(s, std::nullopt, "the mounted robot was not measured: " + in.error, out);
}

}  // namespace ignav::workflow::detail
