#include "ignav/protocol/topics.hpp"

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

}  // namespace ignav::protocol
