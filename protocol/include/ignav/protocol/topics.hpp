// The protocol's names (docs/PROTOCOL.md): topics, their QoS classes, and the roles of DDS
// Security that decide who may publish what. No DDS here: any tool may include it.
#pragma once

#include <string>

namespace ignav::protocol {

namespace topic {
// Commands travel on the topic of the least role that may give them (Role, docs/SECURITY.md).
constexpr const char* kCommandViewer = "ignav/command/viewer";
constexpr const char* kCommandPlanner = "ignav/command/planner";
constexpr const char* kCommandApprover = "ignav/command/approver";
constexpr const char* kReply = "ignav/reply";
constexpr const char* kSliceRequest = "ignav/slice_request";
constexpr const char* kSliceReply = "ignav/slice_reply";
constexpr const char* kSceneRequest = "ignav/scene_request";
constexpr const char* kSceneReply = "ignav/scene_reply";
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
constexpr const char* kStructures = "ignav/state/structures";
// Background jobs' outcomes: one instance, the last 64 kept (Qos::kStateOfMany).
constexpr const char* kJobOutcome = "ignav/state/job_outcome";
}  // namespace topic

// Several robots on one domain (docs/DEPLOYMENT.md): a server and its clients put every reader
// and writer in the DDS partition of the server's robot id, "ignav/robot/<id>". A partition, not
// a key: it scopes every topic without a field in each type, DDS matches nothing across robots
// (a command for one robot never reaches another's server), and DDS Security permissions grant
// topics per partition, so an approver of one robot cannot publish approvals to another.
constexpr const char* kRobotPartitionPrefix = "ignav/robot/";
constexpr const char* kAnyRobot = "*";  // a reader of every robot's partition (ignavctl robots)
std::string robotPartition(const std::string& robot_id);  // kAnyRobot: "ignav/robot/*"
// Why `id` cannot be a robot id ("" when it can): 1-64 of A-Z a-z 0-9 . _ - (no partition
// wildcards, readable in a log and a file name).
std::string robotIdProblem(const std::string& id);

// State topics: reliable, transient-local, keep-last 1 per instance (a late joiner sees the
// present). Requests and replies: reliable, volatile, keep-last 64. kStateOfMany: a state topic
// read from several writers at once (Health across robots), whose one instance would keep only
// the last writer's sample: transient-local, keep-last 64.
enum class Qos { kState, kRequest, kStateOfMany };

// The roles of DDS Security, each allowed the command topics of those before it. Approvals
// (approver) and emergency stops (every authenticated participant) have topics of their own.
enum class Role { kViewer, kPlanner, kApprover };
const char* toString(Role role);      // "viewer" | "planner" | "approver"
const char* commandTopic(Role role);  // topic::kCommandViewer, ...
constexpr Role kRoles[] = {Role::kViewer, Role::kPlanner, Role::kApprover};

}  // namespace ignav::protocol
