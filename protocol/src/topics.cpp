#include "ignav/protocol/topics.hpp"

#include <string>

namespace ignav::protocol {

const char* toString(Role role) {
  switch (role) {
    case Role::kViewer:
      return "viewer";
    case Role::kPlanner:
      return "planner";
    case Role::kApprover:
      return "approver";
  }
  return "?";
}

const char* commandTopic(Role role) {
  switch (role) {
    case Role::kViewer:
      return topic::kCommandViewer;
    case Role::kPlanner:
      return topic::kCommandPlanner;
    case Role::kApprover:
      return topic::kCommandApprover;
  }
  return topic::kCommandViewer;
}

std::string robotPartition(const std::string& robot_id) {
  return kRobotPartitionPrefix + robot_id;
}

std::string robotIdProblem(const std::string& id) {
  if (id.empty()) return "is empty";
  if (id.size() > 64) return "is longer than 64 characters";
  for (const char c : id) {
    const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                       c == '.' || c == '_' || c == '-';
    if (!plain) {
      return std::string("has '") + c + "'; a robot id is letters, digits, '.', '_' and '-'";
    }
  }
  return "";
}

}  // namespace ignav::protocol
