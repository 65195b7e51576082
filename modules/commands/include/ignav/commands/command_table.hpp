// Every input the workflow takes, declared once (issue 22): its name, its number on the wire, who
// may send it, what it carries, what it is for. The wire kinds, the reducer's shape checks, the
// role topics, ignavctl's subcommands, the web gateway's commands and docs/PROTOCOL.md's command
// table are derived from this one table (kInputRows at the end of this file, next to the enum).
// Only std: clients build against it (through ignav::protocol) without the workflow stack (issue
// 39). Adding a command: docs/ARCHITECTURE.md, "Adding a command".
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "ignav/core/table_order.hpp"

namespace ignav::commands {

// Client commands first, then what the server itself feeds in.
enum class InputKind {
  kLoadVolume,
  kSetFiducials,
  kAutoFiducials,
  kAddTarget,
  kMoveTarget,
  kRemoveTarget,
  kClearTargets,
  kReorderTargets,
  kLockPlan,
  kUnlockPlan,
  kStop,
  kResume,
  kEmergencyStop,
  kResetEmergency,
  kQuery,
  kApprove,
  kRequestApproval,
  kHome,
  kSetRegistration,
  kManual,
  kCheckReady,
  kPing,
  kLoadConfirmation,
  kPlaceSeed,
  kAcceptSeed,
  kRejectSeed,
  kFitTissue,
  kUseTissue,
  kDiscardTissue,
  kPauseAt,
  kScanNeedle,
  kReaim,
  kLoadStructures,
  kStructureRole,
  kOverrideClearance,
  kProposeTargets,
  kAcceptProposals,
  kPlaceRobot,
  kPlanSeeds,
  kComputeDose,
  kConfigLoaded,
  kVolumeLoaded,
  kVolumeLoadFailed,
  kFiducialsDetected,
  kFiducialDetectionFailed,
  kSegmentDone,
  kControllerFault,
  kServerRestarted,
  kConfirmationMeasured,
  kConfirmationFailed,
  kNeedleScanned,
  kNeedleScanFailed,
  kStructuresLoaded,
  kStructuresLoadFailed,
  kTargetsProposed,
  kTargetProposalFailed,
  kRobotPlaced,
  kRobotPlacementFailed,
  kPlacementChecked,
  kPlacementCheckFailed,
  kDoseComputed,
  kDoseFailed,
};

// Who may give a command: each role may do what the one before it may, and more. Commands travel
// on the DDS topic of their role, so that DDS Security permissions decide (docs/SECURITY.md).
enum class ClientRole { kViewer, kPlanner, kApprover };
const char* toString(ClientRole role);  // "viewer" | "planner" | "approver"

// Limits on what one command may carry (oversized sequences are rejected, not truncated).
// Points or ids in one command (a plan's own limit, planning.max_targets, may be lower).
constexpr std::size_t kMaxTargets = 100;  // per insertion (paper §V)
constexpr std::size_t kMaxIdLength = 128;
constexpr std::size_t kMaxPathLength = 4096;

// "Any number" in Arguments (up to kMaxTargets, the limit of one command).
constexpr std::size_t kAnyCount = static_cast<std::size_t>(-1);

// What a command carries in Command's fields (path, points, ids, matrix). A field it does not
// name must be empty; counts are exact unless kAnyCount. The texts say what each field is, for
// ignavctl's help and docs/PROTOCOL.md.
struct Arguments {
  const char* path_is = nullptr;       // nullptr: carries no path
  const char* path_choices = nullptr;  // "robot|targeting": the path is one of these
  const char* path_word = nullptr;     // how a person's usage names it ("NAME"); nullptr: PATH
  // The path names a file or folder on the server: one that does not exist is refused before
  // the command is acknowledged (the reducer does no I/O).
  bool path_is_server_file = false;
  std::size_t points = 0;
  const char* points_are = nullptr;
  std::size_t ids = 0;
  const char* ids_are = nullptr;
  const char* matrix_is = nullptr;  // nullptr: carries no matrix
  bool matrix_optional = false;     // may come without one (on the wire: all zeros)

  constexpr Arguments path(const char* is, const char* choices = nullptr) const {
    Arguments a = *this;
    a.path_is = is;
    a.path_choices = choices;
    return a;
  }
  constexpr Arguments name(const char* is) const {  // a name, not a file, in Command.path
    Arguments a = path(is);
    a.path_word = "NAME";
    return a;
  }
  constexpr Arguments millimetres(const char* is) const {  // a number of mm in Command.path
    Arguments a = path(is);
    a.path_word = "MM";
    return a;
  }
  constexpr Arguments text(const char* is) const {  // words for a person, in Command.path
    Arguments a = path(is);
    a.path_word = "TEXT";
    return a;
  }
  constexpr Arguments serverFile(const char* is) const {
    Arguments a = path(is);
    a.path_is_server_file = true;
    return a;
  }
  constexpr Arguments withPoints(std::size_t n, const char* are) const {
    Arguments a = *this;
    a.points = n;
    a.points_are = are;
    return a;
  }
  constexpr Arguments withIds(std::size_t n, const char* are) const {
    Arguments a = *this;
    a.ids = n;
    a.ids_are = are;
    return a;
  }
  constexpr Arguments matrix(const char* is) const {
    Arguments a = *this;
    a.matrix_is = is;
    return a;
  }
  constexpr Arguments optionalMatrix(const char* is) const {
    Arguments a = matrix(is);
    a.matrix_optional = true;
    return a;
  }
};

// How the workflow treats an input, beyond its transitions.
enum InputTraits : unsigned {
  kPlain = 0,
  kFromClients = 1u << 0,  // a client command (else the server feeds it in)
  // Changes nothing: no revision, no journal record, and a pending approval request survives it.
  kQuestion = 1u << 1,
  // Judged against the controller: the server stamps it with a reading taken after every command
  // it sent (docs/ARCHITECTURE.md).
  kNeedsReading = 1u << 2,
  kEveryPhase = 1u << 3,  // allowed in every phase, which it leaves as it is
  // Releases motion (approve): judged on a reading begun after it arrived, so that motors moved
  // by hand a moment before are seen before anything is accepted (issue 38).
  kReleasesMotion = 1u << 4,
};

// Command.kind for an input that is no Command (approve has a topic of its own; server inputs).
constexpr std::int32_t kNoWireKind = -1;

struct InputSpec {
  InputKind kind;
  const char* name;        // "load_volume": the journal's, the replies' and the clients' name
  std::int32_t wire_kind;  // Command.kind: fixed forever once published
  ClientRole role;         // the least role that may give it
  unsigned traits;         // InputTraits
  Arguments args;
  const char* help;  // one line: what it does
};

// The table (kInputRows), in InputKind order.
const std::vector<InputSpec>& inputTable();
const InputSpec& specOf(InputKind kind);
// A client command by name or by Command.kind; nullptr when none is.
const InputSpec* commandNamed(std::string_view name);
const InputSpec* commandOfWireKind(std::int32_t wire_kind);

const char* toString(InputKind kind);  // "load_volume", ...
bool isCommand(InputKind kind);        // issued by clients (the rest come from the server)
bool isQuestion(InputKind kind);       // changes nothing (kQuestion)
// Inputs the reducer judges against the controller: the server stamps them with a fresh reading.
bool needsControllerReading(InputKind kind);
bool releasesMotion(InputKind kind);  // kReleasesMotion: a reading begun after it arrived

// Command.path holds words for a person (Arguments::text): ignavctl takes them last, joined.
bool isText(const Arguments& args);
// The arguments for a person: "PATH (a server-side ...)", "ID X,Y,Z", ... in ignavctl's order
// (path, ids, points, matrix; words for a person last).
std::string usageOf(const InputSpec& spec);

// ---- The table: one row per InputKind, in its order (checked when compiling) ----
// Adding a command: its enumerator above and its row here; docs/ARCHITECTURE.md, "Adding a
// command", for the rest.
namespace detail {

using I = InputKind;
using R = ClientRole;
constexpr Arguments kNone{};
constexpr unsigned kCommand = kFromClients;
constexpr unsigned kServer = kPlain;

// The wire kinds 0-19 are the IDL CommandKind enum's values from before the table (issue 22), so
// clients built against it still work.
inline constexpr InputSpec kInputRows[] = {
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
     kNone.name("the new tissue profile's name (letters, digits, _ or -)"),
     "fit the extended bicycle model's λ1, λ2 to the measured errors (seed 000); the profile is "
     "usable by use_tissue, and written to the session folder as a configs/tissues.yaml entry"},
    {I::kUseTissue, "use_tissue", 26, R::kPlanner, kCommand,
     kNone.name("a tissue profile: the configured one or one fitted in this session; none: aim "
                "without compensation"),
     "aim every target so that the tip, deflected as this tissue's model predicts, lands on it "
     "(compensated joints; the approval request shows nominal and compensated)"},
    {I::kDiscardTissue, "discard_tissue", 27, R::kPlanner, kCommand,
     kNone.name("a tissue profile fitted in this session"),
     "forget a fitted tissue (a fit judged wrong): use_tissue no longer offers it and "
     "tissues_fitted.yaml drops it; the plan's aim, if it is this one, returns to none (with the "
     "plan open; a locked plan is refused)"},
    {I::kPauseAt, "pause_at", 28, R::kPlanner, kCommand,
     kNone.withIds(1, "a target not reached yet")
         .millimetres("the stylet's depth to stop at (mm, more than 0 and at least 1 mm short "
                      "of the target's; none: go all the way)"),
     "stop this target's insertion part-way, the stylet out by MM, for an intermittent CT "
     "(scan_needle) and a re-aim (reaim); the rest is a motion approved of its own"},
    {I::kScanNeedle, "scan_needle", 29, R::kPlanner, kCommand,
     kNone
         .serverFile("a server-side intermittent CT with the needle in: DICOM folder or file, "
                     ".nrrd/.nhdr, .mha/.mhd")
         .optionalMatrix("the scan's image -> robot transform (row-major 4x4, p_robot = M * "
                         "p_lps): the needle in touches the markers on its axis, so give the "
                         "session's registration (or one computed elsewhere); without it the "
                         "markers are found and compared"),
     "with the needle stopped part-way (pause_at): find its shape and tip on the scan, refit the "
     "tissue with that path and propose re-aimed joints for the rest of this insertion and the "
     "targets after it, in the background (TargetState.replan shows the proposal; the request "
     "for the rest as aimed ends, request_approval renews it)"},
    {I::kReaim, "reaim", 30, R::kPlanner, kCommand, kNone,
     "adopt the re-aim scan_needle proposed: the targets it names are aimed with its joints, and "
     "the approval request shows nominal, previously aimed and re-aimed joints with their "
     "predicted landings"},
    {I::kLoadStructures, "load_structures", 31, R::kPlanner, kCommand,
     kNone.serverFile("a server-side segmentation of the session's CT: 3D Slicer .seg.nrrd, "
                      "a .nrrd/.nhdr/.mha/.mhd label map with a Slicer colour table beside it "
                      "(<stem>.ctbl), a DICOM RT Structure Set or a DICOM SEG (in the CT's frame "
                      "of reference)"),
     "load the patient's structures on the CT in the background (their distance fields too): "
     "StructuresState shows loading, then the structures with their roles (the site's, "
     "server.yaml site:), or why the file was refused; every target's path is then checked "
     "against the avoided ones"},
    {I::kStructureRole, "structure_role", 32, R::kPlanner, kCommand,
     kNone.text("NAME ROLE [MARGIN_MM]: a loaded structure, target | avoid | shown, and for "
                "avoid the margin in mm (0-10)"),
     "give a structure its role (overrides the site's); the targets are checked again"},
    {I::kOverrideClearance, "override_clearance", 33, R::kPlanner, kCommand,
     kNone.withIds(1, "a target too close to a structure")
         .text("REASON: why its path may pass so close (journaled, shown in the approval "
               "request and the report)"),
     "plan this one target although its needle passes closer to a structure than the margin "
     "allows"},
    {I::kProposeTargets, "propose_targets", 34, R::kPlanner, kCommand,
     kNone.text("STRUCTURE SPACING_MM: a loaded structure to fill, and the lattice's spacing in "
                "mm (1-30)"),
     "propose targets that fill a structure from this one insertion, in the background: a "
     "lattice of the spacing, aligned with the robot, clipped to the structure, to what the "
     "needle reaches and to every clearance, ordered as the plan would visit them "
     "(StructuresState.proposed); accept_proposals makes them targets"},
    {I::kAcceptProposals, "accept_proposals", 35, R::kPlanner, kCommand,
     kNone.withIds(kAnyCount, "proposed targets to accept (none: all of them)"),
     "make proposed targets the plan's targets, checked again as they are added"},
    {I::kPlaceRobot, "place_robot", 36, R::kPlanner, kCommand,
     kNone.text("STRUCTURE [from SIDE]: a loaded structure to cover, and the side the needle "
                "comes from (inferior, superior, anterior, posterior, left, right; default: the "
                "site's approach)"),
     "propose where to mount the robot, in the background: the entry point and insertion axis, "
     "within the site's limits, from which one insertion covers the most of the structure with "
     "every clearance kept, with alternatives (StructuresState.placements); once the robot is "
     "mounted and registered, how far it stands from the proposal and what it covers there"},
    {I::kPlanSeeds, "plan_seeds", 37, R::kPlanner, kCommand,
     kNone.text("STRUCTURE [model=NAME] [rx=GY] [strength=U] [spacing=MM] [implanted=none]: a "
                "target structure to dose, and what differs from the site's dosimetry: defaults "
                "(seed model, prescription, every seed's air-kerma strength, the candidates' "
                "lattice); the confirmation CT's seeds count unless implanted=none"),
     "plan the fewest seeds that give the structure its prescription (V100 ≥ 95 %, D90 ≥ "
     "100 %) while every avoided structure stays within the site's dose limits, in the "
     "background, among the positions the needle reaches with every clearance kept; after a "
     "confirmation CT, the seeds it found are counted as implanted (their dose, planned against "
     "delivered, the cold spots) and the plan adds to them; the seeds "
     "arrive as proposed targets (StructuresState.proposed, the dose in its message) that "
     "accept_proposals makes the plan's"},
    {I::kComputeDose, "compute_dose", 38, R::kPlanner, kCommand,
     kNone.text("STRUCTURE [model=NAME] [rx=GY] [strength=U]: the target structure to judge "
                "the dose on and the seeds' model, prescription and air-kerma strength (default: "
                "the accepted seed plan's, else the site's dosimetry: defaults; after a seed "
                "plan, the structure may be left out)"),
     "compute the dose of the plan's targets as seeds and, after a confirmation CT, of the seeds "
     "found on it, in the background: the metrics planned and delivered (StructuresState.dose_*), "
     "isodose lines on every slice, and into the session folder the dose as NRRD and DICOM RT "
     "Dose, an RT Plan with the seeds, the RT Structure Set and the DVH plot; accepting a seed "
     "plan and a confirmation CT after one start it by themselves"},
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
    {I::kNeedleScanned, "needle_scanned", kNoWireKind, R::kApprover, kServer, kNone,
     "the server found the paused needle on an intermittent CT and computed the re-aim it "
     "proposes"},
    {I::kNeedleScanFailed, "needle_scan_failed", kNoWireKind, R::kApprover, kServer, kNone,
     "an intermittent CT could not be loaded, registered, or show the paused needle, or no re-aim "
     "came of it: why"},
    {I::kStructuresLoaded, "structures_loaded", kNoWireKind, R::kApprover, kServer, kNone,
     "a structure load the server ran finished: the structures and their distance fields"},
    {I::kStructuresLoadFailed, "structures_load_failed", kNoWireKind, R::kApprover, kServer, kNone,
     "a structure load the server ran failed: why"},
    {I::kTargetsProposed, "targets_proposed", kNoWireKind, R::kApprover, kServer, kNone,
     "a target proposal the server ran finished: the targets, in the order they would be "
     "visited"},
    {I::kTargetProposalFailed, "target_proposal_failed", kNoWireKind, R::kApprover, kServer, kNone,
     "a target proposal the server ran found none, or more than the plan can take: why"},
    {I::kRobotPlaced, "robot_placed", kNoWireKind, R::kApprover, kServer, kNone,
     "a robot placement the server ran finished: the poses, the best first"},
    {I::kRobotPlacementFailed, "robot_placement_failed", kNoWireKind, R::kApprover, kServer, kNone,
     "a robot placement the server ran found no pose: why"},
    {I::kPlacementChecked, "placement_checked", kNoWireKind, R::kApprover, kServer, kNone,
     "the mounted robot measured against the placement proposed: how far, what it covers"},
    {I::kPlacementCheckFailed, "placement_check_failed", kNoWireKind, R::kApprover, kServer, kNone,
     "the mounted robot could not be measured against the placement: why"},
    {I::kDoseComputed, "dose_computed", kNoWireKind, R::kApprover, kServer, kNone,
     "a dose computation the server ran finished: the dose of the seeds, planned and delivered"},
    {I::kDoseFailed, "dose_failed", kNoWireKind, R::kApprover, kServer, kNone,
     "a dose computation the server ran could not finish: why"},
};

static_assert(inEnumOrder(kInputRows, &InputSpec::kind),
              "a row of the command table is out of InputKind order: it would give an input "
              "another's name and rules");

}  // namespace detail

}  // namespace ignav::commands
