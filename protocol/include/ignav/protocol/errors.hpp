// What the protocol layer throws.
#pragma once

#include <stdexcept>

namespace ignav::protocol {

struct DdsError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// DDS Security refused: this identity's permissions do not allow the topic or the entity.
struct PermissionDenied : DdsError {
  using DdsError::DdsError;
};
// Which robot a client talks to cannot be decided: none found, several and none named, or the
// one named is not there (client.hpp chooseRobot).
struct RobotNotChosen : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// No reply (or no expected state) in time.
struct Timeout : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace ignav::protocol
