// The workflow's values: phases, inputs, the session state and the effects a step asks for.
// Nothing here reads a clock, touches a socket or owns a thread (DESIGN.md).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/actuation/transmission.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/kinematics/solver.hpp"
#include "ignav/registration/point_registration.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::workflow {

enum class Phase {
  kStartup,
  kImaging,
  kRegistration,
  kPlanning,
  kPlanLocked,
  kStopped,
  kEmergency
};
constexpr Phase kAllPhases[] = {Phase::kStartup,  Phase::kImaging,    Phase::kRegistration,
                                Phase::kPlanning, Phase::kPlanLocked, Phase::kStopped,
                                Phase::kEmergency};
const char* toString(Phase phase);  // "startup", "imaging", ...

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
  kConfigLoaded,      // the server started with a valid robot config
  kVolumeLoaded,      // a load the server ran finished
  kVolumeLoadFailed,  // ... or failed
};
constexpr InputKind kAllInputs[] = {
    InputKind::kLoadVolume,    InputKind::kSetFiducials,   InputKind::kAutoFiducials,
    InputKind::kAddTarget,     InputKind::kMoveTarget,     InputKind::kRemoveTarget,
    InputKind::kClearTargets,  InputKind::kReorderTargets, InputKind::kLockPlan,
    InputKind::kUnlockPlan,    InputKind::kStop,           InputKind::kResume,
    InputKind::kEmergencyStop, InputKind::kResetEmergency, InputKind::kQuery,
    InputKind::kConfigLoaded,  InputKind::kVolumeLoaded,   InputKind::kVolumeLoadFailed};
const char* toString(InputKind kind);  // "load_volume", ...
bool isCommand(InputKind kind);        // issued by clients (the rest come from the server)

// Limits on what one command may carry (oversized sequences are rejected, not truncated).
constexpr std::size_t kMaxTargets = 100;  // per insertion (paper §V)
constexpr std::size_t kMaxIdLength = 128;
constexpr std::size_t kMaxPathLength = 4096;

struct LoadedCt {
  std::shared_ptr<const volume::Volume> volume;
  std::string source;  // what the client asked to load
  std::string description;
};

struct Input {
  InputKind kind = InputKind::kQuery;
  double time_s = 0.0;  // stamped by the server; the reducer never reads a clock
  std::string client_id;
  std::uint64_t request_id = 0;
  std::string path;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::uint32_t> ids;
  LoadedCt loaded;    // kVolumeLoaded
  std::string error;  // kVolumeLoadFailed
};

struct Reply {
  std::string client_id;
  std::uint64_t request_id = 0;
  bool accepted = false;
  std::string error_code;  // "" when accepted
  std::string message;
  std::uint32_t target_id = 0;
  std::uint64_t revision = 0;
};

// A clicked target and what it means for the robot, re-derived whenever the registration or the
// robot changes (never dropped).
struct Target {
  std::uint32_t id = 0;
  Eigen::Vector3d lps_mm = Eigen::Vector3d::Zero();
  bool registered = false;
  Eigen::Vector3d robot_mm = Eigen::Vector3d::Zero();
  kinematics::InverseSolution solution;
  actuation::Steps steps;
  double tre_mm = 0.0;
  bool tre_warning = false;
  std::string message;         // person-readable reachability
  std::string status() const;  // "planned" | "unreachable" | "unregistered"
};

struct VolumeStatus {
  std::string status = "none";  // none | loading | loaded | failed
  std::string source;
  std::string message;
};

struct RegistrationStatus {
  std::string status = "none";  // none | registered | rejected
  std::string message;
  bool auto_detected = false;
};

struct Session {
  std::string session_id;
  Phase phase = Phase::kStartup;
  Phase resume_phase = Phase::kImaging;  // where kResume returns to from kStopped
  std::uint64_t revision = 0;
  std::string last_event;
  std::shared_ptr<const config::Robot> robot;
  std::string robot_path;
  LoadedCt ct;
  VolumeStatus volume_status;
  std::optional<registration::Registration> registration;
  RegistrationStatus registration_status;
  std::vector<Target> targets;  // in planned order
  std::uint32_t next_target_id = 1;
  std::uint64_t accepted = 0;
  std::uint64_t rejected = 0;
  // The last replies per client, so a repeated request_id is answered again, not re-executed.
  std::map<std::string, std::map<std::uint64_t, Reply>> replies;
};

// What the server must do after a step, in this order: append the journal records (durably),
// publish the changed state, send the replies, start the volume load.
struct Effects {
  std::vector<std::string> journal;  // JSON lines
  bool workflow_changed = false;
  bool robot_changed = false;
  bool volume_changed = false;
  bool registration_changed = false;
  std::vector<std::uint32_t> targets_changed;
  std::vector<std::uint32_t> targets_removed;
  std::vector<Reply> replies;
  std::optional<std::string> load_volume;  // path to load, then feed kVolumeLoaded/Failed
};

struct Step {
  Session session;
  Effects effects;
};

}  // namespace ignav::workflow
