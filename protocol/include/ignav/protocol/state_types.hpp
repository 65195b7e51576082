// The state topics (protocol/idl/ignav.idl says what each field means): each value, its one list
// of fields (JSON name, member, C member(s)) and its topic. Part of types.hpp.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "ignav/protocol/fields.hpp"
#include "ignav/protocol/topics.hpp"
#include "ignav/protocol/values.hpp"

namespace ignav::protocol {

struct WorkflowState {
  std::string session_id;
  std::string phase;
  std::vector<std::string> allowed_commands;
  std::uint64_t revision = 0;
  std::string last_event;
  std::string safety_notice;              // "" unless the site has weakened a safeguard
  std::vector<std::uint32_t> target_ids;  // every target there is, in planned order
};
template <>
struct Fields<WorkflowState> {
  using T = WorkflowState;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(session_id), IGNAV_FIELD(phase), IGNAV_FIELD(allowed_commands),
                      IGNAV_FIELD(revision), IGNAV_FIELD(last_event), IGNAV_FIELD(safety_notice),
                      IGNAV_FIELD(target_ids));
};
IGNAV_TOPIC_OF(WorkflowState, topic::kWorkflow, Qos::kState);

struct RobotState {
  std::string name;
  std::string config_path;
  double r_min_mm = 0.0;
  double r_max_mm = 0.0;
  double cannula_travel_mm = 0.0;
  double stylet_travel_mm = 0.0;
  double feasible_volume_cm3 = 0.0;
  std::vector<Point3> feature_points_robot;
  std::string tissue;  // "" = none
};
template <>
struct Fields<RobotState> {
  using T = RobotState;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(name), IGNAV_FIELD(config_path), IGNAV_FIELD(r_min_mm), IGNAV_FIELD(r_max_mm),
      IGNAV_FIELD(cannula_travel_mm), IGNAV_FIELD(stylet_travel_mm),
      IGNAV_FIELD(feasible_volume_cm3), IGNAV_FIELD(feature_points_robot), IGNAV_FIELD(tissue));
};
IGNAV_TOPIC_OF(RobotState, topic::kRobot, Qos::kState);

struct VolumeState {
  std::string status;  // none | loading | loaded | failed
  std::string source;
  std::string message;
  std::array<std::uint32_t, 3> dims{};
  std::array<double, 3> spacing_mm{};
  RowMajor4 ijk_to_lps{};
  double hu_min = 0.0;
  double hu_max = 0.0;
  std::array<std::uint64_t, 2> progress{};  // files read, of all (while loading)
};
template <>
struct Fields<VolumeState> {
  using T = VolumeState;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(status), IGNAV_FIELD(source), IGNAV_FIELD(message), IGNAV_FIELD(dims),
      IGNAV_FIELD(spacing_mm), IGNAV_FIELD(ijk_to_lps), IGNAV_FIELD(hu_min), IGNAV_FIELD(hu_max),
      field("progress", &T::progress,
            [](auto& msg) { return std::tie(msg.progress_done, msg.progress_total); }));
};
IGNAV_TOPIC_OF(VolumeState, topic::kVolume, Qos::kState);

struct RegistrationState {
  std::string status;  // none | registered | rejected
  std::string message;
  std::string kind;  // similarity | rigid
  std::vector<Point3> image_points;
  std::vector<Point3> robot_points;
  RowMajor4 image_to_robot{};
  double scale = 0.0;
  double fre_mm = 0.0;
  std::vector<double> residuals_mm;
  bool auto_detected = false;
};
template <>
struct Fields<RegistrationState> {
  using T = RegistrationState;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(status), IGNAV_FIELD(message), IGNAV_FIELD(kind), IGNAV_FIELD(image_points),
      IGNAV_FIELD(robot_points), IGNAV_FIELD(image_to_robot), IGNAV_FIELD(scale),
      IGNAV_FIELD(fre_mm), IGNAV_FIELD(residuals_mm), IGNAV_FIELD(auto_detected));
};
IGNAV_TOPIC_OF(RegistrationState, topic::kRegistration, Qos::kState);

struct ClearanceState {
  std::string structure;
  double distance_mm = 0.0;
  double margin_mm = 0.0;
  double uncertainty_mm = 0.0;
  std::string part;
  Point3 needle_lps;
  Point3 structure_lps;
  bool beyond_reach = false;
  bool too_close = false;
};
template <>
struct Fields<ClearanceState> {
  using T = ClearanceState;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(structure), IGNAV_FIELD(distance_mm), IGNAV_FIELD(margin_mm),
      IGNAV_FIELD(uncertainty_mm), IGNAV_FIELD(part), IGNAV_FIELD(needle_lps),
      IGNAV_FIELD(structure_lps), IGNAV_FIELD(beyond_reach), IGNAV_FIELD(too_close));
};

struct TargetState {
  std::uint32_t id = 0;
  Point3 lps;
  Point3 robot;
  bool registered = false;
  bool reachable = false;
  std::string reach;  // reachable | inside_min_radius | beyond_max_radius | too_shallow | too_deep
  std::string message;
  JointValues joints{};
  MotorSteps steps{};
  double tre_mm = 0.0;
  bool tre_warning = false;
  std::uint32_t order = 0;
  std::optional<double> predicted_deviation_mm;  // a model prediction, when there is one
  std::string status;  // planned | reached | unreachable | unregistered | outside_volume
  bool outside_volume = false;
  std::string path_warning;
  std::vector<Point3> path_lps;
  bool compensated = false;
  std::string aim_tissue;
  JointValues nominal_joints{};
  Point3 nominal_landing_robot;
  Point3 predicted_landing_robot;
  double pause_z_s_mm = 0.0;  // pause_at's stylet depth; 0: inserted all the way at once
  bool paused = false;
  JointValues paused_joints{};
  bool reaimed = false;
  JointValues previous_joints{};
  Point3 previous_landing_robot;
  Point3 reaimed_landing_robot;
  std::string replan;
  std::vector<ClearanceState> clearances;
  std::string clearance_refusal;
  std::string clearance_override;
};
template <>
struct Fields<TargetState> {
  using T = TargetState;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(id), IGNAV_FIELD(lps), IGNAV_FIELD(robot), IGNAV_FIELD(registered),
      IGNAV_FIELD(reachable), IGNAV_FIELD(reach), IGNAV_FIELD(message),
      field("joints", &T::joints,
            [](auto& msg) { return std::tie(msg.theta_c_rad, msg.z_c_mm, msg.z_s_mm); }),
      IGNAV_FIELD(steps), IGNAV_FIELD(tre_mm), IGNAV_FIELD(tre_warning), IGNAV_FIELD(order),
      field(
          "predicted_deviation_mm", &T::predicted_deviation_mm,
          [](auto& msg) { return std::tie(msg.predicted_deviation_mm, msg.deviation_predicted); }),
      IGNAV_FIELD(status), IGNAV_FIELD(outside_volume), IGNAV_FIELD(path_warning),
      IGNAV_FIELD(path_lps), IGNAV_FIELD(compensated), IGNAV_FIELD(aim_tissue),
      IGNAV_FIELD(nominal_joints), IGNAV_FIELD(nominal_landing_robot),
      IGNAV_FIELD(predicted_landing_robot), IGNAV_FIELD(pause_z_s_mm), IGNAV_FIELD(paused),
      IGNAV_FIELD(paused_joints), IGNAV_FIELD(reaimed), IGNAV_FIELD(previous_joints),
      IGNAV_FIELD(previous_landing_robot), IGNAV_FIELD(reaimed_landing_robot), IGNAV_FIELD(replan),
      IGNAV_FIELD(clearances), IGNAV_FIELD(clearance_refusal), IGNAV_FIELD(clearance_override));
};
IGNAV_TOPIC_OF(TargetState, topic::kTarget, Qos::kState);

struct StructureInfo {
  std::string name;
  std::array<double, 3> colour_rgb{};
  std::string role;
  double margin_mm = 0.0;
  std::uint64_t voxels = 0;
  double volume_cm3 = 0.0;
  std::array<double, 6> bounds_lps{};
};
template <>
struct Fields<StructureInfo> {
  using T = StructureInfo;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(name), IGNAV_FIELD(colour_rgb), IGNAV_FIELD(role), IGNAV_FIELD(margin_mm),
      IGNAV_FIELD(voxels), IGNAV_FIELD(volume_cm3), IGNAV_FIELD(bounds_lps));
};

struct ProposedTargetInfo {
  std::uint32_t id = 0;
  std::array<double, 3> lps{};
};
template <>
struct Fields<ProposedTargetInfo> {
  using T = ProposedTargetInfo;
  static constexpr auto list = std::make_tuple(IGNAV_FIELD(id), IGNAV_FIELD(lps));
};

struct PlacementInfo {
  double coverage = 0.0;
  std::array<double, 3> origin_lps{};
  std::array<double, 3> axis_lps{};
  std::array<double, 3> entry_lps{};
  double tilt_deg = 0.0;
  double shift_mm = 0.0;
  double skin_distance_mm = 0.0;
  bool skin_seen = false;
};
template <>
struct Fields<PlacementInfo> {
  using T = PlacementInfo;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(coverage), IGNAV_FIELD(origin_lps), IGNAV_FIELD(axis_lps),
                      IGNAV_FIELD(entry_lps), IGNAV_FIELD(tilt_deg), IGNAV_FIELD(shift_mm),
                      IGNAV_FIELD(skin_distance_mm), IGNAV_FIELD(skin_seen));
};

struct DoseMetricsInfo {
  std::string structure;
  std::string which;  // planned | delivered
  double d90_percent = std::numeric_limits<double>::quiet_NaN();
  double v100 = std::numeric_limits<double>::quiet_NaN();
  double v150 = std::numeric_limits<double>::quiet_NaN();
  double d10_percent = std::numeric_limits<double>::quiet_NaN();
  double dmax_percent = std::numeric_limits<double>::quiet_NaN();
  double d2cc_gy = std::numeric_limits<double>::quiet_NaN();
};
template <>
struct Fields<DoseMetricsInfo> {
  using T = DoseMetricsInfo;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(structure), IGNAV_FIELD(which), IGNAV_FIELD(d90_percent), IGNAV_FIELD(v100),
      IGNAV_FIELD(v150), IGNAV_FIELD(d10_percent), IGNAV_FIELD(dmax_percent), IGNAV_FIELD(d2cc_gy));
};

struct StructuresState {
  std::string status;  // none | loading | loaded | failed
  std::string source;
  std::string message;
  std::string site;
  std::vector<StructureInfo> structures;
  std::string proposal_status;  // none | proposing | proposed | failed
  std::string proposal_message;
  std::vector<ProposedTargetInfo> proposed;
  std::uint64_t proposal_progress_done = 0;  // proposing: units done, of total
  std::uint64_t proposal_progress_total = 0;
  std::string placement_status;  // none | placing | placed | failed
  std::string placement_message;
  std::string placement_structure;
  std::uint64_t placement_progress_done = 0;  // placing: the search's units done, of total
  std::uint64_t placement_progress_total = 0;
  std::vector<PlacementInfo> placements;  // the best first
  std::string mounted_status;             // none | measuring | measured | failed
  std::string mounted_message;
  double mounted_coverage = std::numeric_limits<double>::quiet_NaN();
  double mounted_entry_mm = std::numeric_limits<double>::quiet_NaN();
  double mounted_axis_deg = std::numeric_limits<double>::quiet_NaN();
  std::string dose_status;  // none | computing | computed | failed
  std::string dose_message;
  std::vector<DoseMetricsInfo> dose;
};
template <>
struct Fields<StructuresState> {
  using T = StructuresState;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(status), IGNAV_FIELD(source), IGNAV_FIELD(message), IGNAV_FIELD(site),
      IGNAV_FIELD(structures), IGNAV_FIELD(proposal_status), IGNAV_FIELD(proposal_message),
      IGNAV_FIELD(proposed), IGNAV_FIELD(proposal_progress_done),
      IGNAV_FIELD(proposal_progress_total), IGNAV_FIELD(placement_status),
      IGNAV_FIELD(placement_message), IGNAV_FIELD(placement_structure),
      IGNAV_FIELD(placement_progress_done), IGNAV_FIELD(placement_progress_total),
      IGNAV_FIELD(placements), IGNAV_FIELD(mounted_status), IGNAV_FIELD(mounted_message),
      IGNAV_FIELD(mounted_coverage), IGNAV_FIELD(mounted_entry_mm), IGNAV_FIELD(mounted_axis_deg),
      IGNAV_FIELD(dose_status), IGNAV_FIELD(dose_message), IGNAV_FIELD(dose));
};
IGNAV_TOPIC_OF(StructuresState, topic::kStructures, Qos::kState);

struct ErrorStats {
  std::uint32_t count = 0;
  double mean_mm = 0.0, sd_mm = 0.0, min_mm = 0.0, max_mm = 0.0, rms_mm = 0.0;
};
template <>
struct Fields<ErrorStats> {
  using T = ErrorStats;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(count), IGNAV_FIELD(mean_mm), IGNAV_FIELD(sd_mm),
                      IGNAV_FIELD(min_mm), IGNAV_FIELD(max_mm), IGNAV_FIELD(rms_mm));
};

struct SeedState {
  std::uint32_t id = 0;
  std::string kind = "seed";  // seed | tip
  Point3 lps;
  Point3 robot;
  double length_mm = 0.0;
  double width_mm = 0.0;
  bool placed = false;
  bool rejected = false;
  std::uint32_t target_id = 0;
  std::vector<Point3> path_lps;
};
template <>
struct Fields<SeedState> {
  using T = SeedState;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(id), IGNAV_FIELD(kind), IGNAV_FIELD(lps), IGNAV_FIELD(robot),
                      IGNAV_FIELD(length_mm), IGNAV_FIELD(width_mm), IGNAV_FIELD(placed),
                      IGNAV_FIELD(rejected), IGNAV_FIELD(target_id), IGNAV_FIELD(path_lps));
};

struct MeasuredTargetState {
  std::uint32_t target_id = 0;
  std::uint32_t seed_id = 0;
  std::string matched;  // detected | tip | accepted | placed
  Point3 planned_robot, actual_robot, planned_lps, actual_lps, error_robot, error_lps;
  double error_mm = 0.0;
  double lateral_mm = 0.0;
  double radial_mm = 0.0;
  double tangential_mm = 0.0;
  double depth_mm = 0.0;
  std::optional<Point3> predicted_robot;
  double predicted_error_mm = 0.0;
};
template <>
struct Fields<MeasuredTargetState> {
  using T = MeasuredTargetState;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(target_id), IGNAV_FIELD(seed_id), IGNAV_FIELD(matched),
                      IGNAV_FIELD(planned_robot), IGNAV_FIELD(actual_robot),
                      IGNAV_FIELD(planned_lps), IGNAV_FIELD(actual_lps), IGNAV_FIELD(error_robot),
                      IGNAV_FIELD(error_lps), IGNAV_FIELD(error_mm), IGNAV_FIELD(lateral_mm),
                      IGNAV_FIELD(radial_mm), IGNAV_FIELD(tangential_mm), IGNAV_FIELD(depth_mm),
                      field("predicted_robot", &T::predicted_robot,
                            [](auto& msg) { return std::tie(msg.predicted_robot, msg.predicted); }),
                      IGNAV_FIELD(predicted_error_mm));
};

struct FittedTissueState {
  std::string name;
  double lambda1 = 0.0, lambda2 = 0.0, lambda1_se = 0.0, lambda2_se = 0.0;
  double rms_mm = 0.0, rms_bicycle_mm = 0.0, rms_no_deflection_mm = 0.0;
  std::uint32_t targets = 0;
  std::string limit;
  std::string yaml;
};
template <>
struct Fields<FittedTissueState> {
  using T = FittedTissueState;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(name), IGNAV_FIELD(lambda1), IGNAV_FIELD(lambda2),
                      IGNAV_FIELD(lambda1_se), IGNAV_FIELD(lambda2_se), IGNAV_FIELD(rms_mm),
                      IGNAV_FIELD(rms_bicycle_mm), IGNAV_FIELD(rms_no_deflection_mm),
                      IGNAV_FIELD(targets), IGNAV_FIELD(limit), IGNAV_FIELD(yaml));
};

struct VerificationState {
  std::string status;  // none | measuring | measured | unmatched
  std::string source;
  std::string measuring_source;
  std::string message;
  bool registration_reused = false;
  double marker_shift_mm = 0.0;
  double fre_mm = 0.0;
  RowMajor4 image_to_robot{};
  std::string detection_summary;
  std::vector<SeedState> seeds;
  std::vector<MeasuredTargetState> targets;
  std::vector<std::uint32_t> missing_targets;
  std::vector<std::uint32_t> extra_seeds;
  ErrorStats error, lateral, depth;
  std::string summary;
  std::vector<FittedTissueState> fitted_tissues;
  std::string aim_tissue;
};
template <>
struct Fields<VerificationState> {
  using T = VerificationState;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(status), IGNAV_FIELD(source), IGNAV_FIELD(measuring_source), IGNAV_FIELD(message),
      IGNAV_FIELD(registration_reused), IGNAV_FIELD(marker_shift_mm), IGNAV_FIELD(fre_mm),
      IGNAV_FIELD(image_to_robot), IGNAV_FIELD(detection_summary), IGNAV_FIELD(seeds),
      IGNAV_FIELD(targets), IGNAV_FIELD(missing_targets), IGNAV_FIELD(extra_seeds),
      IGNAV_FIELD(error), IGNAV_FIELD(lateral), IGNAV_FIELD(depth), IGNAV_FIELD(summary),
      IGNAV_FIELD(fitted_tissues), IGNAV_FIELD(aim_tissue));
};
IGNAV_TOPIC_OF(VerificationState, topic::kVerification, Qos::kState);

struct PlannedMove {
  std::string kind;  // retract_stylet | translate_cannula | rotate_cannula | deploy_stylet
  MotorSteps steps{};
  double duration_s = 0.0;
};
template <>
struct Fields<PlannedMove> {
  using T = PlannedMove;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(kind), IGNAV_FIELD(steps), IGNAV_FIELD(duration_s));
};

struct ApprovalState {
  std::string status;  // none | pending
  std::uint64_t plan_id = 0;
  std::string digest;
  std::uint32_t target_id = 0;  // 0: the final retraction of the stylet
  std::string summary;
  MotorSteps from_steps{};
  std::vector<PlannedMove> moves;
  double duration_s = 0.0;
  double tre_mm = 0.0;
  double expires_in_s = 0.0;       // at publication
  double expires_at_unix_s = 0.0;  // the server's clock
  std::vector<std::string> approvers;
};
template <>
struct Fields<ApprovalState> {
  using T = ApprovalState;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(status), IGNAV_FIELD(plan_id), IGNAV_FIELD(digest), IGNAV_FIELD(target_id),
      IGNAV_FIELD(summary), IGNAV_FIELD(from_steps), IGNAV_FIELD(moves), IGNAV_FIELD(duration_s),
      IGNAV_FIELD(tre_mm), IGNAV_FIELD(expires_in_s), IGNAV_FIELD(expires_at_unix_s),
      IGNAV_FIELD(approvers));
};
IGNAV_TOPIC_OF(ApprovalState, topic::kApprovalState, Qos::kState);

struct MotionState {
  std::string controller;  // simulated | galil host:port
  std::string state;       // disconnected | idle | moving | fault
  std::string lifecycle;   // unconfigured | connecting | active | lost | shut_down
  std::string fault;
  std::uint64_t plan_id = 0;  // 0: none under way
  std::uint32_t target_id = 0;
  std::uint32_t move_index = 0;  // 1-based, of move_count
  std::uint32_t move_count = 0;
  std::string move_kind;
  MotorSteps steps{};           // reported
  MotorSteps goal_steps{};      // where the move under way ends
  MotorSteps verified_steps{};  // last position the workflow verified
  JointValues joints{};         // of the reported steps
  Point3 tip_robot;
  std::optional<Point3> tip_lps;  // with a registration
  double uptime_s = 0.0;
  std::vector<Point3> needle_lps;  // with a registration: cannula base, cannula tip, stylet arc
};
template <>
struct Fields<MotionState> {
  using T = MotionState;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(controller), IGNAV_FIELD(state), IGNAV_FIELD(lifecycle), IGNAV_FIELD(fault),
      IGNAV_FIELD(plan_id), IGNAV_FIELD(target_id), IGNAV_FIELD(move_index),
      IGNAV_FIELD(move_count), IGNAV_FIELD(move_kind), IGNAV_FIELD(steps), IGNAV_FIELD(goal_steps),
      IGNAV_FIELD(verified_steps),
      field("joints", &T::joints,
            [](auto& msg) { return std::tie(msg.theta_c_rad, msg.z_c_mm, msg.z_s_mm); }),
      IGNAV_FIELD(tip_robot),
      field("tip_lps", &T::tip_lps,
            [](auto& msg) { return std::tie(msg.tip_lps, msg.tip_lps_valid); }),
      IGNAV_FIELD(uptime_s), IGNAV_FIELD(needle_lps));
};
IGNAV_TOPIC_OF(MotionState, topic::kMotion, Qos::kState);

struct Health {
  std::string version;
  std::string session_id;
  std::string session_dir;
  double uptime_s = 0.0;
  std::uint64_t commands_accepted = 0;
  std::uint64_t commands_rejected = 0;
  std::string journal;  // "ok", or why the journal cannot be written
  std::uint32_t igtl_clients = 0;
  double server_time_unix_s = 0.0;
  std::string robot_id;
  std::string host;
  double started_unix_s = 0.0;
};
template <>
struct Fields<Health> {
  using T = Health;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(version), IGNAV_FIELD(session_id), IGNAV_FIELD(session_dir),
      IGNAV_FIELD(uptime_s), IGNAV_FIELD(commands_accepted), IGNAV_FIELD(commands_rejected),
      IGNAV_FIELD(journal), IGNAV_FIELD(igtl_clients), IGNAV_FIELD(server_time_unix_s),
      IGNAV_FIELD(robot_id), IGNAV_FIELD(host), IGNAV_FIELD(started_unix_s));
};
IGNAV_TOPIC_OF(Health, topic::kHealth, Qos::kState);

}  // namespace ignav::protocol
