// The phantom CT's grid for workflow tests: the geometry the reducer checks targets against (it
// must show every target), without rendering a voxel.
#pragma once

#include <memory>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/phantom.hpp"

namespace ignav::test {

inline std::shared_ptr<const volume::Volume> phantomCtGrid(const config::Robot& robot) {
  auto ct = std::make_shared<volume::Volume>();
  ct->geometry = volume::phantomGeometry(
      registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan)
          .value()
          .spec);
  return ct;
}

}  // namespace ignav::test
