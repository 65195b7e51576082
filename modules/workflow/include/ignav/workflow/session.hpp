// The workflow's values: phases, inputs, the session state and the effects a step asks for.
// Nothing here reads a clock, touches a socket or owns a thread (DESIGN.md).
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/actuation/controller.hpp"
#include "ignav/actuation/transmission.hpp"
#include "ignav/anatomy/distance_field.hpp"
#include "ignav/anatomy/site.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/config/tissue_profiles.hpp"
#include "ignav/dosimetry/seed_plan.hpp"
#include "ignav/kinematics/solver.hpp"
#include "ignav/placement/robot_placement.hpp"
#include "ignav/planning/insertion_plan.hpp"
#include "ignav/registration/fiducial_detection.hpp"
#include "ignav/registration/point_registration.hpp"
#include "ignav/volume/volume.hpp"
#include "ignav/workflow/closed_loop.hpp"
#include "ignav/workflow/inputs.hpp"

namespace ignav::workflow {

enum class Phase {
  kStartup,
  kImaging,
  kRegistration,
  kPlanning,
  kPlanLocked,  // an approval request for the next motion is pending
  kMoving,      // an approved motion is under way
  kAtTarget,    // the stylet is at a target; the next motion awaits approval
  kDone,        // every target visited, the stylet retracted
  kStopped,
  kEmergency,
  kFault,  // the controller failed or its position is in doubt
  kManual  // the robot is moved by hand (or joystick); commands wait until it is handed back
};
constexpr Phase kAllPhases[] = {Phase::kStartup,   Phase::kImaging,    Phase::kRegistration,
                                Phase::kPlanning,  Phase::kPlanLocked, Phase::kMoving,
                                Phase::kAtTarget,  Phase::kDone,       Phase::kStopped,
                                Phase::kEmergency, Phase::kFault,      Phase::kManual};
const char* toString(Phase phase);  // "startup", "imaging", ...
// The phases that interrupt the workflow; resume (after reset_emergency for emergency and fault)
// leaves them for the phase the first interruption left.
constexpr bool isInterruption(Phase p) {
  return p == Phase::kStopped || p == Phase::kEmergency || p == Phase::kFault ||
         p == Phase::kManual;
}
// Where resume may lead: every phase but the interruptions and moving (a move in flight is
// planned again from where the robot stands, plan_locked, and approved again).
constexpr Phase kResumePhases[] = {Phase::kStartup,  Phase::kImaging,    Phase::kRegistration,
                                   Phase::kPlanning, Phase::kPlanLocked, Phase::kAtTarget,
                                   Phase::kDone};

// Limits on what one command may carry: the command table's (ignav/commands/command_table.hpp).
using commands::kMaxIdLength;
using commands::kMaxPathLength;
using commands::kMaxTargets;

// Who may release motion and for how long a request stays valid (server.yaml `approval:`).
struct ApprovalPolicy {
  // Client ids or, with DDS Security on, certificate subjects; empty: nobody can approve.
  std::vector<std::string> approvers;
  double expiry_s = 120.0;
  planning::PlanningLimits limits;  // ordering and rotation limit
  double speed_steps_s = 2000.0;    // the controller's profile, for the duration estimates
  double acceleration_steps_s2 = 8000.0;
};

struct LoadedCt {
  std::shared_ptr<const volume::Volume> volume;
  std::string source;  // what the client asked to load
  std::string description;
};

// The patient's structures on the CT (issue 41): as a structure load read them (roles from the
// file and the site), with a distance field per structure, built off the event thread.
struct LoadedStructures {
  std::shared_ptr<const anatomy::StructureSet> set;
  std::vector<std::shared_ptr<const anatomy::DistanceField>> fields;  // one per structure
};

// How far a target's needle passes from one avoided structure (issue 41): its whole body (the
// cannula, then the stylet, each with its outer radius) at its closest.
struct StructureClearance {
  std::string structure;
  // From the needle's surface to the structure's; negative: the needle enters it that deep.
  double distance_mm = 0.0;
  double margin_mm = 0.0;  // the structure's
  // What the distance may be wrong by there (2 SD along the way to the structure): the expected
  // registration error at that point and, aiming with a fitted tissue, the landing's spread; and
  // the deflection a tissue profile predicts that the aim does not compensate.
  double uncertainty_mm = 0.0;
  std::string part;                                            // "cannula" | "stylet"
  Eigen::Vector3d needle_lps_mm = Eigen::Vector3d::Zero();     // on the centreline
  Eigen::Vector3d structure_lps_mm = Eigen::Vector3d::Zero();  // the nearest surface point
  bool beyond_reach = false;  // farther than the field reaches: distance_mm is a lower bound
  bool tooClose() const { return distance_mm - uncertainty_mm < margin_mm; }
};

// Where to mount the robot (place_robot, issue 41): on a CT taken before it is mounted, the poses
// from which one insertion covers the most of a structure with every clearance kept; once it is
// mounted and registered, how far it stands from the best of them and what it covers there.
struct MountedPlacement {
  placement::PoseDeviation deviation;
  placement::Coverage coverage;  // from where it stands
  placement::SkinEntry skin;     // where its axis meets the skin
};

struct ComputedDose;  // below: the dose of the session's seeds

struct Input {
  InputKind kind = InputKind::kQuery;
  double time_s = 0.0;    // Unix seconds, stamped by the server; the reducer never reads a clock
  std::string client_id;  // self-declared by the client
  std::uint64_t request_id = 0;
  // Who sent it, as the DDS edge knows it (docs/SECURITY.md): the role whose topic carried the
  // command ("viewer" | "planner" | "approver" | "any"), and with DDS Security on, the sender's
  // authenticated certificate subject ("CN=approver,O=ignav,C=NL"; "" when not known).
  std::string role;
  std::string identity;
  std::string path;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::uint32_t> ids;
  LoadedCt loaded;    // kVolumeLoaded; kConfirmationMeasured: the scan's volume (not journaled)
  std::string error;  // kVolumeLoadFailed, kFiducialDetectionFailed
  // kFiducialsDetected, kFiducialDetectionFailed: the detection they answer (the revision of the
  // auto_fiducials that asked for it); `path` is the CT it ran on, and `points` the matched
  // markers' image points (LPS, in the robot's feature point order).
  std::uint64_t job = 0;
  std::string summary;  // kFiducialsDetected: what the detection found, for a person
  // Replayed from a journal record: that record's format ("v"); 0 when live. A format-1
  // auto_fiducials detected and registered within its own step (before issue 22).
  int journal_format = 0;
  std::uint64_t plan_id = 0;  // kApprove
  std::string digest;         // kApprove
  // kSetRegistration: p_robot = matrix * p_lps (homogeneous; rotation, translation, scale).
  std::optional<Eigen::Matrix4d> matrix;
  // kConfigLoaded: who may approve, for how long, the controller's profile. Journaled with the
  // input, so recovery and offline replay judge approvals by the same rules.
  std::optional<ApprovalPolicy> policy;
  // kConfigLoaded: the tissue the session's deflection predictions use (none: no prediction).
  std::optional<config::TissueProfile> tissue;
  // kConfigLoaded: the robot this session drives and the session's own identity, made at random
  // by the server when the session began (a folder's name is not unique in a department).
  std::string robot_id;
  std::string session_uuid;
  // kConfirmationMeasured: the seeds found on the confirmation CT (`points`: the robot's markers
  // there, in the model's order; `path`: the scan; `summary`: what the search found). Also
  // kNeedleScanned's, with the re-aim the scan led to.
  std::vector<FoundSeed> seeds;
  std::optional<ReaimProposal> reaim;
  // kStructuresLoaded: the structures read and their fields (`path` the file; `summary` names
  // each with its voxels, so replay can tell a changed file).
  LoadedStructures structures;
  // kRobotPlaced: the poses found, the best first; kPlacementChecked: the mounted robot's.
  std::vector<placement::PlacedPose> placements;
  std::optional<MountedPlacement> mounted;
  // kDoseComputed: the dose of the seeds (`summary` says it, so replay can tell a changed one).
  std::shared_ptr<const ComputedDose> dose;
  // kConfigLoaded: the site's roles for structures by name (server.yaml site:); none: every
  // structure is shown only until structure_role gives it a role.
  std::optional<anatomy::Site> site;
  // What the controller said just before this input (approve, resume, reset_emergency, home and
  // the controller's own inputs): the reducer judges the robot by it, and replay sees the same.
  std::optional<actuation::ControllerStatus> controller;
};

struct Reply {
  std::string client_id;
  std::uint64_t request_id = 0;
  bool accepted = false;
  std::string error_code;  // "" when accepted
  std::string message;
  std::uint32_t target_id = 0;
  std::uint64_t revision = 0;
  double server_time_s = 0.0;  // Unix s: when the server took the command (ping's answer)
  std::uint64_t job = 0;       // the background job the command started (JobOutcome.job); 0: none
};

// Aiming with a tissue profile (use_tissue, issue 23): the joints whose tip, deflected as the
// profile's extended bicycle model predicts, lands on the target (compensation::compensate).
struct CompensatedAim {
  std::string profile;  // the tissue profile's name
  kinematics::Joints joints;
  Eigen::Vector3d landing_robot_mm = Eigen::Vector3d::Zero();  // of `joints`, predicted
  // Where the nominal joints (Target::solution) would land in that tissue: the error compensated.
  Eigen::Vector3d nominal_landing_robot_mm = Eigen::Vector3d::Zero();
  double residual_mm = 0.0;  // |landing - target|
};

// A clicked target and what it means for the robot, re-derived whenever the registration or the
// robot changes (never dropped).
struct Target {
  std::uint32_t id = 0;
  Eigen::Vector3d lps_mm = Eigen::Vector3d::Zero();
  bool registered = false;
  Eigen::Vector3d robot_mm = Eigen::Vector3d::Zero();
  kinematics::InverseSolution solution;       // exact IK: the nominal joints
  std::optional<CompensatedAim> compensated;  // with a tissue profile chosen
  actuation::Steps steps;                     // of commandedJoints()
  double tre_mm = 0.0;
  bool tre_warning = false;
  // Model prediction (extended bicycle model, the session's tissue): how far the cannula's tip
  // drifts sideways after its zc mm of insertion. NaN without a tissue profile.
  double predicted_deviation_mm = std::numeric_limits<double>::quiet_NaN();
  bool reached = false;    // the stylet tip was brought here (verified steps)
  double reached_s = 0.0;  // when (Unix seconds)
  // The joints it was reached with (commandedJoints() then): what a confirmation CT measures and
  // a tissue fit explains, whatever the registration or the aim changed since.
  kinematics::Joints reached_joints;
  // A CT is loaded and the target lies outside it: tissue nobody has seen. add_target and
  // move_target refuse such points; a target becomes one when a CT that misses it is loaded later.
  bool outside_volume = false;
  // How much of the planned path (needlePathLps) runs outside the loaded CT, and, for a person,
  // a warning saying so ("" when none does). A warning only: the cannula may well start outside
  // the scanned field.
  double path_outside_ct_mm = 0.0;
  std::string path_warning;
  // Aiming with a tissue profile and the compensated pose is out of reach (or the model does not
  // converge): why. The target is then unreachable for this plan.
  std::string compensation_refusal;
  // Re-planning during the insertion (issue 40): the stylet depth its motion stops at first
  // (pause_at; the rest is approved of its own), where it stopped, and the aim scan_needle's
  // re-aim gave it (reaim). A plan choice and where the needle has been: kept whatever is
  // evaluated again; a re-aim is dropped when the target is (its joints answer another plan).
  std::optional<double> pause_z_s_mm;
  std::optional<kinematics::Joints> paused;
  std::optional<ReaimedAim> reaimed;
  std::string replan;  // for a person: the last intermittent CT's outcome or the re-aim taken
  // The whole needle against every avoided structure (issue 41), in the structures' order; why
  // it is refused ("" when every clearance holds); and the reason an operator gave to plan it
  // all the same (override_clearance; a plan choice, dropped when the target moves).
  std::vector<StructureClearance> clearances;
  std::string clearance_refusal;
  std::string clearance_override;
  std::string message;  // person-readable reachability
  // "planned" | "reached" | "unreachable" | "unregistered" | "outside_volume" | "too_close"
  std::string status() const;
  bool tooClose() const { return !clearance_refusal.empty() && clearance_override.empty(); }
  // Registered, reachable, (aiming with a tissue) compensated and clear of the avoided
  // structures (or overridden): lock_plan may plan it.
  bool plannable() const {
    return registered && solution.reachable() && compensation_refusal.empty() && !tooClose();
  }
  // The joints the plan moves to: re-aimed ones, else the compensated ones with a tissue profile,
  // else the nominal.
  const kinematics::Joints& commandedJoints() const {
    if (reaimed) return reaimed->joints;
    return compensated ? compensated->joints : solution.joints;
  }
  // The joints the aim had before any re-aim (compensated or nominal).
  const kinematics::Joints& aimedJoints() const {
    return compensated ? compensated->joints : solution.joints;
  }
};

// What one approval releases: the moves to one target (or the final retraction), as the exact
// step increments the controller will receive, from an exact starting position.
struct MotionRequest {
  std::uint64_t plan_id = 0;
  std::string digest;           // SHA-256 (hex) of canonicalText(): what would be sent
  std::uint32_t target_id = 0;  // 0: the final retraction of the stylet
  actuation::Steps from;        // absolute motor position the moves start from
  std::vector<planning::JointMove> moves;
  // The insertion stops part-way (pause_at): the stylet's depth there. The target is then not
  // reached but paused; the digest covers it.
  std::optional<double> pause_z_s_mm;
  double duration_s = 0.0;  // with the controller's profile
  double tre_mm = 0.0;      // expected registration error at the target
  double issued_s = 0.0;
  double expires_s = 0.0;
  std::string summary;  // for a person: target, joints, steps per motor, duration, TRE
};

// One approved motion as the report lists it.
struct MotionRecord {
  std::uint64_t plan_id = 0;
  std::uint32_t target_id = 0;  // 0: the final retraction
  std::string approved_by;
  double approved_s = 0.0;
  double ended_s = -1.0;  // < 0 while under way
  std::string outcome;    // arrived | stopped | emergency | fault: ... | restarted
};

namespace detail {
struct ApprovalCheck;
}

// What makes a motion unique in a department, beside its steps: the robot it is for and the
// session it belongs to. Two robots' digests differ even when their folders and plans are alike.
struct MotionScope {
  std::string robot_id;      // "" in a session journaled before issue 38 (digest text v1)
  std::string session_id;    // the session folder's name
  std::string session_uuid;  // random, made at the session's start and journaled; "" as robot_id
};

// A motion an operator approved, exactly as its request showed it (issue 22): only the approval
// check (detail::ApprovalCheck, motion.cpp) creates one, and a move for the controller can only
// be built from one (ControllerCommand::move).
class ApprovedMotion {
 public:
  const MotionRequest& request() const { return request_; }
  const MotionScope& scope() const { return scope_; }
  // Does the request still hash to the digest the operator approved? (The executor asks just
  // before a move goes to the controller.)
  bool intact() const;

 private:
  friend struct detail::ApprovalCheck;
  ApprovedMotion(MotionScope scope, MotionRequest request)
      : scope_(std::move(scope)), request_(std::move(request)) {}
  MotionScope scope_;
  MotionRequest request_;
};

// An approved motion under way (or interrupted by a stop, an emergency or a fault).
struct ActiveMotion {
  ApprovedMotion approved;
  std::size_t segment = 0;        // the move under way
  actuation::Steps segment_from;  // where that move started
  bool interrupted = false;
  const MotionRequest& request() const { return approved.request(); }
};

struct VolumeStatus {
  std::string status = "none";  // none | loading | loaded | failed
  std::string source;
  std::string message;
};

struct RegistrationStatus {
  // none | detecting (auto_fiducials: the markers are being detected in the background; a
  // registration from before stays in use meanwhile) | registered | rejected (the last attempt
  // failed and there is no registration)
  std::string status = "none";
  std::string message;
  bool auto_detected = false;
};

// Per structure of the loaded set: the role the plan gives it (the file's or site's, or
// structure_role's).
struct StructureRoleChoice {
  anatomy::Role role = anatomy::Role::kShown;
  double margin_mm = 0.0;
};

struct StructuresStatus {
  std::string status = "none";  // none | loading | loaded | failed
  std::string source;
  std::string message;
  std::uint64_t loading = 0;  // the load_structures awaited (its revision); 0: none
  LoadedStructures loaded;    // loaded: the structures
  std::vector<StructureRoleChoice> roles;
};

// Targets proposed to fill a structure (propose_targets, issue 41): lattice points inside it
// whose needles reach them with every clearance kept, in the order the plan would visit them.
struct ProposedTarget {
  std::uint32_t id = 0;  // 1, 2, ... in that order; accept_proposals names them
  Eigen::Vector3d lps_mm = Eigen::Vector3d::Zero();
};

// plan_seeds (issue 42): a proposal whose targets are a seed plan's seeds.
struct SeedPlanAsk {
  std::string seed_model;       // its name
  std::string seed_model_path;  // <the site's seed_models>/<name>.yaml
  double prescription_Gy = 0.0;
  double strength_U = 0.0;
  // The confirmation CT's seeds are in the patient: their dose counts, the plan adds to them
  // (re-planning during the implant); `implanted=none` leaves them out.
  bool implanted = true;
};

struct TargetProposals {
  std::string status = "none";           // none | proposing | proposed | failed
  std::optional<SeedPlanAsk> seed_plan;  // set: the targets are a seed plan's seeds
  std::string structure;                 // the one filled
  double spacing_mm = 0.0;               // the lattice's
  std::string message;                   // what the proposal found, or why none
  std::uint64_t proposing = 0;           // the propose_targets awaited (its revision); 0: none
  std::vector<ProposedTarget> targets;   // not yet accepted
};

// The dose of the session's seeds (issue 42, part 5): the targets as the seeds a plan leaves and,
// after a confirmation CT, the seeds found on it, each on the same grid (the CT's voxels around the
// structure dosed) and judged on every voxel of the structures.
struct SeedDose {
  std::string what;  // "planned" | "delivered"
  std::size_t seeds = 0;
  std::shared_ptr<const std::vector<float>> dose_Gy;  // ComputedDose::grid's, i fastest
  dosimetry::PlanEvaluation evaluation;
  std::vector<dosimetry::ColdSpot> cold_spots;  // the structure's, largest first
};

struct ComputedDose {
  SeedPlanAsk seeds;      // the model, strength and prescription
  std::string structure;  // the target dosed
  volume::Geometry grid;
  std::vector<SeedDose> doses;     // planned, then delivered when a confirmation CT found seeds
  std::vector<std::string> files;  // left in the session folder (relative to it)
  const SeedDose* latest() const { return doses.empty() ? nullptr : &doses.back(); }
};

struct DoseStatus {
  std::string status = "none";  // none | computing | computed | failed
  std::string message;          // the metrics, planned and delivered, or why none
  std::uint64_t computing = 0;  // the dose computation awaited (its revision); 0: none
  // What the plan's seeds are (accept_proposals of a seed plan, or compute_dose) and the structure
  // their dose is judged on: a confirmation CT computes the delivered dose with them.
  std::optional<SeedPlanAsk> seeds;
  std::string structure;
  // The seeds as they were when the dose was asked (the job's, and replay's, whatever changed
  // since): a seed at each plannable target, along its needle; the confirmation CT's.
  std::vector<dosimetry::Seed> planned_seeds, delivered_seeds;
  double asked_s = 0.0;  // Unix s, the asking input's (the RT Plan's date): no clock in the job
  std::shared_ptr<const ComputedDose> computed;
};

// place_robot's outcome in the session (MountedPlacement above).
struct RobotPlacement {
  std::string status = "none";               // none | placing | placed | failed
  std::string structure;                     // the one covered
  anatomy::PlacementLimits limits;           // the site's, with the approach asked for
  std::string message;                       // what the search found, or why nothing
  std::uint64_t placing = 0;                 // the place_robot awaited (its revision); 0: none
  std::vector<placement::PlacedPose> poses;  // the best first, then alternatives
  double structure_cm3 = 0.0;                // the structure's volume, for the figures
  // After a registration: the check awaited (its revision; 0: none) and its outcome.
  std::uint64_t checking = 0;
  std::optional<MountedPlacement> mounted;
  std::string mounted_message;
};

struct Session {
  std::string session_id;
  std::string robot_id;      // config_loaded's (journaled); "" before issue 38
  std::string session_uuid;  // config_loaded's (journaled); "" before issue 38
  Phase phase = Phase::kStartup;
  Phase resume_phase = Phase::kImaging;  // where kResume returns to (one of kResumePhases)
  std::uint64_t revision = 0;
  std::string last_event;
  std::shared_ptr<const config::Robot> robot;
  std::string robot_path;
  LoadedCt ct;
  VolumeStatus volume_status;
  std::optional<registration::Registration> registration;
  RegistrationStatus registration_status;
  // The marker detection under way (auto_fiducials): its job, the revision of the auto_fiducials
  // that asked for it; 0 when none is. A new CT or a registration given meanwhile drops it (its
  // result is then ignored).
  std::uint64_t detecting = 0;
  // The revision of the load_volume that asked for the CT loaded (or loading) now.
  std::uint64_t ct_revision = 0;
  std::vector<Target> targets;  // in planned order
  std::uint32_t next_target_id = 1;
  bool order_fixed = false;  // reorder_targets was used: lock_plan keeps the user's order
  ApprovalPolicy policy;
  std::optional<config::TissueProfile> tissue;  // the predictions' (server.yaml tissue:)
  // The closed loop (issue 23): the confirmation CT and its errors, the tissues fitted from them,
  // and the profile the plan aims with (use_tissue; none: nominal joints).
  Confirmation confirmation;
  // Re-planning during an insertion (issue 40): the intermittent CT being searched (its job, 0:
  // none; the scan; a given registration) and the last re-aim proposed.
  std::uint64_t scanning_needle = 0;
  std::string scanning_source;
  std::optional<Eigen::Matrix4d> scanning_matrix;
  std::optional<ReaimProposal> reaim;
  // The patient's structures on the CT (issue 41) and the site's roles for them.
  StructuresStatus structures;
  TargetProposals proposals;
  DoseStatus dose;
  RobotPlacement robot_placement;
  std::optional<anatomy::Site> site;
  std::vector<FittedTissue> fitted_tissues;
  std::optional<config::TissueProfile> aim_tissue;
  actuation::Steps position;  // last verified absolute motor position (zero = home)
  std::optional<MotionRequest> pending;
  std::optional<ActiveMotion> motion;
  std::uint64_t next_plan_id = 1;
  std::string fault;                  // why the phase is fault (or the last controller fault)
  std::vector<MotionRecord> motions;  // every approved motion, in order
  std::uint64_t accepted = 0;
  std::uint64_t rejected = 0;
  // The last replies per client, so a repeated request_id is answered again, not re-executed.
  std::map<std::string, std::map<std::uint64_t, Reply>> replies;
};

enum class ControllerAction { kMove, kStop, kAbort, kHome, kClearFault };
const char* toString(ControllerAction action);  // "move", "stop", ...

// What the reducer asks of the controller. A move exists only as one move of an ApprovedMotion.
class ControllerCommand {
 public:
  static ControllerCommand stop() { return ControllerCommand(ControllerAction::kStop); }
  static ControllerCommand abort() { return ControllerCommand(ControllerAction::kAbort); }
  static ControllerCommand home() { return ControllerCommand(ControllerAction::kHome); }
  static ControllerCommand clearFault() { return ControllerCommand(ControllerAction::kClearFault); }
  // The `segment`th move of `approved` (which must have one).
  static ControllerCommand move(const ApprovedMotion& approved, std::size_t segment);

  ControllerAction action() const { return action_; }
  const actuation::Steps& increments() const { return increments_; }  // kMove; else zero
  bool isHalt() const {
    return action_ == ControllerAction::kStop || action_ == ControllerAction::kAbort;
  }
  // For a move: its approval intact (the digest still matches what was approved) and the
  // increments exactly its segment's. The executor checks this before it sends; anything else
  // releases no motion. True for every other action.
  bool releasable() const;
  const std::optional<ApprovedMotion>& approval() const { return approved_; }
  // A move: where its segment starts, from the approval alone (the request's start plus the
  // segments before it). The controller sends it only with the robot at rest there.
  actuation::Steps segmentStart() const;

 private:
  explicit ControllerCommand(ControllerAction action) : action_(action) {}
  ControllerAction action_;
  actuation::Steps increments_;
  std::optional<ApprovedMotion> approved_;  // kMove
  std::size_t segment_ = 0;
};

// A marker detection for the server to run off the event thread (auto_fiducials): everything it
// needs, immutable, and the job its result must name. workflow::detectFiducials() runs it.
struct FiducialDetectionJob {
  std::uint64_t job = 0;
  std::shared_ptr<const volume::Volume> volume;
  std::string ct_source;
  registration::FiducialSearch search;
  std::vector<Eigen::Vector3d> model_mm;  // the robot's feature points, in their order
};

// The kinds of background work (background_jobs.hpp).
enum class JobKind;

// What became of a background job, from the step that took its outcome: for a client waiting on
// the job its command started (Reply::job), so that it need not guess from the state topics.
struct JobOutcome {
  std::uint64_t job = 0;
  std::string kind;    // the job's kind: "marker detection", ...
  std::string input;   // the outcome input: "fiducials_detected", ...
  std::string status;  // done | failed | stale (no longer awaited: nothing changed)
  std::string message;
  std::uint64_t revision = 0;  // the session's after the step
};

// What the server must do after a step, in this order: append the journal records (durably),
// publish the changed state, send the replies, start the volume load or the marker detection.
struct Effects {
  std::vector<std::string> journal;  // JSON lines
  bool workflow_changed = false;
  bool robot_changed = false;
  bool volume_changed = false;
  bool registration_changed = false;
  std::vector<std::uint32_t> targets_changed;
  std::vector<std::uint32_t> targets_removed;
  std::vector<Reply> replies;
  // Background jobs to start, made from the new session (background_jobs.hpp: pending).
  std::vector<JobKind> start_jobs;
  std::optional<JobOutcome> job_outcome;  // this step took a background job's outcome
  // The report's slices to render (server/reports.hpp): every target's when the plan is locked, the
  // one just reached when the needle arrives.
  bool plan_slices = false;
  std::optional<std::uint32_t> reached_target_slices;
  bool confirmation_changed = false;  // VerificationState
  bool structures_changed = false;    // StructuresState
  bool tissue_fitted = false;         // write the fitted profiles to the session folder
  bool approval_changed = false;
  bool motion_changed = false;
  // Halts (stop, abort) go to the controller before anything else, even the journal (DESIGN.md
  // safety invariant 3); the rest after the journal holds the input that caused them.
  std::vector<ControllerCommand> controller;
};

struct Step {
  Session session;
  Effects effects;
};

}  // namespace ignav::workflow
