// Every input the workflow takes, declared once (issue 22): its name, its number on the wire, who
// may send it, what it carries, what it is for. The wire kinds, the reducer's shape checks, the
// role topics, ignavctl's subcommands, the web gateway's commands and docs/PROTOCOL.md's command
// table are derived from this one table (kInputs in command_table.cpp). Only std: clients build
// against it (through ignav::protocol) without the workflow stack (issue 39). Adding a command:
// docs/ARCHITECTURE.md, "Adding a command".
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

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

// The table, in InputKind order.
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

// The arguments for a person: "PATH (a server-side ...)", "ID X,Y,Z", ... in ignavctl's order
// (path, ids, points, matrix).
std::string usageOf(const InputSpec& spec);

}  // namespace ignav::commands
