// The protocol's names (docs/PROTOCOL.md): topics, their QoS classes, and the roles of DDS
// Security that decide who may publish what. No DDS here: any tool may include it.
#pragma once

namespace ignav::protocol {

namespace topic {
// Commands travel on the topic of the least role that may give them (Role, docs/SECURITY.md).
constexpr const char* kCommandViewer = "ignav/command/viewer";
constexpr const char* kCommandPlanner = "ignav/command/planner";
constexpr const char* kCommandApprover = "ignav/command/approver";
constexpr const char* kReply = "ignav/reply";
constexpr const char* kSliceRequest = "ignav/slice_request";
constexpr const char* kSliceReply = "ignav/slice_reply";
constexpr const char* kWorkflow = "ignav/state/workflow";
constexpr const char* kRobot = "ignav/state/robot";
constexpr const char* kVolume = "ignav/state/volume";
constexpr const char* kRegistration = "ignav/state/registration";
constexpr const char* kTarget = "ignav/state/target";
constexpr const char* kHealth = "ignav/state/health";
constexpr const char* kApproval = "ignav/approval";
constexpr const char* kEmergencyStop = "ignav/emergency_stop";
constexpr const char* kApprovalState = "ignav/state/approval";
constexpr const char* kMotion = "ignav/state/motion";
constexpr const char* kVerification = "ignav/state/verification";
}  // namespace topic

// State topics: reliable, transient-local, keep-last 1 per instance (a late joiner sees the
// present). Requests and replies: reliable, volatile, keep-last 64.
enum class Qos { kState, kRequest };

// The roles of DDS Security, each allowed the command topics of those before it. Approvals
// (approver) and emergency stops (every authenticated participant) have topics of their own.
enum class Role { kViewer, kPlanner, kApprover };
const char* toString(Role role);      // "viewer" | "planner" | "approver"
const char* commandTopic(Role role);  // topic::kCommandViewer, ...
constexpr Role kRoles[] = {Role::kViewer, Role::kPlanner, Role::kApprover};

}  // namespace ignav::protocol
