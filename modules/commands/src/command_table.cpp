#include "ignav/commands/command_table.hpp"

#include <stdexcept>

#include "ignav/core/table_order.hpp"

namespace ignav::commands {
namespace {

using I = InputKind;
using R = ClientRole;
constexpr Arguments kNone{};
constexpr unsigned kCommand = kFromClients;
constexpr unsigned kServer = kPlain;

// The wire kinds 0-19 are the IDL CommandKind enum's values from before the table (issue 22), so
// clients built against it still work.
const std::vector<InputSpec> kInputs = {
    // kind, name, wire kind, least role, traits, arguments, what it does
    {I::kLoadVolume, "load_volume", 0, R::kPlanner, kCommand,
     kNone.serverFile(
         "a server-side DICOM folder or file, .nrrd/.nhdr, .mha/.mhd, or phantom: (the "
         "built-in phantom)"),
     "load the CT; VolumeState goes loading -> loaded or failed, with progress"},
    {I::kSetFiducials, "set_fiducials", 1, R::kPlanner, kCommand,
     kNone.withPoints(3, "the image points (LPS) of cannula base, cannula tip, stylet tip"),
     "register the image to the robot with three clicked fiducials"},
    {I::kAutoFiducials, "auto_fiducials", 2, R::kPlanner, kCommand, kNone,
     "find the robot's markers on the CT, match them and register, in the background: accepted "
     "when the detection starts (RegistrationState detecting); the outcome shows in "
     "RegistrationState (registered, or rejected with the reason)"},
    {I::kAddTarget, "add_target", 3, R::kPlanner, kCommand, kNone.withPoints(1, "the target (LPS)"),
     "add a target; the reply's target_id names it"},
    {I::kMoveTarget, "move_target", 4, R::kPlanner, kCommand,
     kNone.withIds(1, "the target").withPoints(1, "its new place (LPS)"), "move a target"},
    {I::kRemoveTarget, "remove_target", 5, R::kPlanner, kCommand, kNone.withIds(1, "the target"),
     "remove a target"},
    {I::kClearTargets, "clear_targets", 6, R::kPlanner, kCommand, kNone, "remove every target"},
    {I::kReorderTargets, "reorder_targets", 7, R::kPlanner, kCommand,
     kNone.withIds(kAnyCount, "every target id once, in the new order"),
     "visit the targets in this order (lock_plan then keeps it)"},
    {I::kLockPlan, "lock_plan", 8, R::kPlanner, kCommand, kNone,
     "lock the plan (at least one target, all reachable) and ask for approval of its first "
     "motion"},
    {I::kUnlockPlan, "unlock_plan", 9, R::kPlanner, kCommand, kNone,
     "unlock the plan to edit it; a pending approval request dies"},
    {I::kStop, "stop", 10, R::kPlanner, kCommand, kNone,
     "halt whatever is in progress (a move decelerates to rest) and wait in stopped; already "
     "stopped, manual, in an emergency or a fault: halt the controller again, the phase stays"},
    {I::kResume, "resume", 11, R::kApprover, kCommand | kNeedsReading, kNone,
     "back to the phase the first interruption left (a move in flight: plan_locked, planned "
     "again from where the robot stands; done when nothing is left); from manual, the motors' "
     "position is adopted"},
    {I::kEmergencyStop, "emergency_stop", 12, R::kViewer, kCommand, kNone,
     "abort the controller before anything else happens (also the EmergencyStop topic)"},
    {I::kResetEmergency, "reset_emergency", 13, R::kApprover, kCommand | kNeedsReading, kNone,
     "check the position, clear the fault and go to stopped"},
    {I::kQuery, "query", 14, R::kViewer, kCommand | kQuestion | kEveryPhase, kNone,
     "republish every state topic (a client that lost samples)"},
    {I::kApprove, "approve", kNoWireKind, R::kApprover, kCommand | kNeedsReading | kReleasesMotion,
     kNone,
     "release the pending motion: plan_id and digest exactly as ApprovalState shows them (the "
     "Approval topic)"},
    {I::kRequestApproval, "request_approval", 15, R::kPlanner, kCommand, kNone,
     "a fresh approval request for the next motion (new plan id, new expiry)"},
    {I::kHome, "home", 16, R::kApprover, kCommand | kNeedsReading, kNone,
     "the robot was brought home by hand: its present position becomes zero"},
    {I::kSetRegistration, "set_registration", 17, R::kPlanner, kCommand,
     kNone.matrix("row-major 4x4, p_robot = M * p_lps: a proper similarity computed elsewhere "
                  "(3D Slicer's); the targets' TRE is then unknown"),
     "register with a matrix computed elsewhere"},
    {I::kManual, "manual", 18, R::kPlanner, kCommand | kNeedsReading, kNone,
     "halt and hand the robot to manual control; resume takes it back"},
    {I::kCheckReady, "check_ready", 19, R::kViewer, kCommand | kQuestion | kNeedsReading,
     kNone.path("robot: the controller answers, at rest, no fault; targeting: that, and a "
                "registration exists",
                "robot|targeting"),
     "accepted when ready, refused with the reason when not"},
    {I::kPing, "ping", 20, R::kViewer, kCommand | kQuestion | kEveryPhase, kNone,
     "the server's clock (Unix s) and the session revision, answered at once: for clients "
     "measuring their clock offset and round trip"},
    {I::kLoadConfirmation, "load_confirmation", 21, R::kPlanner, kCommand,
     kNone.serverFile("a server-side confirmation CT: DICOM folder or file, .nrrd/.nhdr, .mha/.mhd")
         .optionalMatrix("the scan's image -> robot transform (row-major 4x4, p_robot = M * "
                         "p_lps) where its markers cannot serve: a needle left in touches those on "
                         "its axis, or the scan leaves the robot out (the session's own "
                         "registration, or one computed elsewhere); without it the markers are "
                         "found and compared"),
     "load a confirmation CT after motion and measure the targeting error of every reached "
     "target, in the background: VerificationState shows measuring, then the seeds, the match "
     "and the errors (or why the scan was refused; the measurement before stays)"},
    {I::kPlaceSeed, "place_seed", 22, R::kPlanner, kCommand,
     kNone.withIds(1, "a reached target").withPoints(1, "its seed on the confirmation CT (LPS)"),
     "the click fallback: this target's seed is here (found or not); the match keeps it"},
    {I::kAcceptSeed, "accept_seed", 23, R::kPlanner, kCommand,
     kNone.withIds(1, "a measured target"),
     "the seed matched to this target is its seed: the match keeps the pair"},
    {I::kRejectSeed, "reject_seed", 24, R::kPlanner, kCommand,
     kNone.withIds(1, "a seed (VerificationState.seeds)"),
     "this is no seed of the plan (a calcification, a seed from before): matched again without it"},
    {I::kFitTissue, "fit_tissue", 25, R::kPlanner, kCommand,
     kNone.path("the new tissue profile's name (letters, digits, _ or -)"),
     "fit the extended bicycle model's λ1, λ2 to the measured errors (seed 000); the profile is "
     "usable by use_tissue, and written to the session folder as a configs/tissues.yaml entry"},
    {I::kUseTissue, "use_tissue", 26, R::kPlanner, kCommand,
     kNone.path("a tissue profile: the configured one or one fitted in this session; none: aim "
                "without compensation"),
     "aim every target so that the tip, deflected as this tissue's model predicts, lands on it "
     "(compensated joints; the approval request shows nominal and compensated)"},
    {I::kConfigLoaded, "config_loaded", kNoWireKind, R::kApprover, kServer, kNone,
     "the server started with a valid robot config"},
    {I::kVolumeLoaded, "volume_loaded", kNoWireKind, R::kApprover, kServer, kNone,
     "a load the server ran finished"},
    {I::kVolumeLoadFailed, "volume_load_failed", kNoWireKind, R::kApprover, kServer, kNone,
     "a load the server ran failed"},
    {I::kFiducialsDetected, "fiducials_detected", kNoWireKind, R::kApprover, kServer, kNone,
     "a marker detection the server ran matched the markers: their image points, to register"},
    {I::kFiducialDetectionFailed, "fiducial_detection_failed", kNoWireKind, R::kApprover, kServer,
     kNone, "a marker detection the server ran found no match (or could not search): why"},
    {I::kSegmentDone, "segment_done", kNoWireKind, R::kApprover, kServer | kNeedsReading, kNone,
     "the controller came to rest after a move the server sent"},
    {I::kControllerFault, "controller_fault", kNoWireKind, R::kApprover, kServer | kNeedsReading,
     kNone, "the controller reported a fault or stopped answering"},
    {I::kServerRestarted, "server_restarted", kNoWireKind, R::kApprover, kServer | kNeedsReading,
     kNone, "recovery finished: approvals die, the position is checked"},
    {I::kConfirmationMeasured, "confirmation_measured", kNoWireKind, R::kApprover, kServer, kNone,
     "the server loaded a confirmation CT and found the robot's markers and the seeds on it"},
    {I::kConfirmationFailed, "confirmation_failed", kNoWireKind, R::kApprover, kServer, kNone,
     "a confirmation CT could not be loaded or its markers were not found: why"},
};

}  // namespace

const char* toString(ClientRole role) {
  switch (role) {
    case ClientRole::kViewer:
      return "viewer";
    case ClientRole::kPlanner:
      return "planner";
    case ClientRole::kApprover:
      return "approver";
  }
  return "unknown";
}

const std::vector<InputSpec>& inputTable() {
  // A row out of place would give an input another's name and rules: refuse to run at all.
  static const bool ok = inEnumOrder(kInputs, &InputSpec::kind);
  if (!ok) throw std::logic_error("workflow input table is not in InputKind order");
  return kInputs;
}

const InputSpec& specOf(InputKind kind) {
  return inputTable().at(static_cast<std::size_t>(kind));
}

const InputSpec* commandNamed(std::string_view name) {
  for (const auto& s : inputTable())
    if ((s.traits & kFromClients) && name == s.name) return &s;
  return nullptr;
}

const InputSpec* commandOfWireKind(std::int32_t wire_kind) {
  if (wire_kind == kNoWireKind) return nullptr;
  for (const auto& s : inputTable())
    if (s.wire_kind == wire_kind) return &s;
  return nullptr;
}

const char* toString(InputKind kind) {
  return specOf(kind).name;
}

bool isCommand(InputKind kind) {
  return (specOf(kind).traits & kFromClients) != 0;
}

bool isQuestion(InputKind kind) {
  return (specOf(kind).traits & kQuestion) != 0;
}

bool needsControllerReading(InputKind kind) {
  return (specOf(kind).traits & kNeedsReading) != 0;
}

bool releasesMotion(InputKind kind) {
  return (specOf(kind).traits & kReleasesMotion) != 0;
}

std::string usageOf(const InputSpec& spec) {
  const Arguments& a = spec.args;
  std::string out;
  auto add = [&](const std::string& word) { out += (out.empty() ? "" : " ") + word; };
  if (a.path_is) add(a.path_choices ? a.path_choices : "PATH");
  auto repeated = [&](std::size_t n, const char* one) {
    if (n == kAnyCount) {
      add(std::string(one) + "...");
    } else {
      for (std::size_t i = 0; i < n; ++i)
        add(one);
    }
  };
  repeated(a.ids, "ID");
  repeated(a.points, "X,Y,Z");
  if (a.matrix_is) add(a.matrix_optional ? "[M11,M12,...,M44]" : "M11,M12,...,M44");
  return out;
}

}  // namespace ignav::commands
