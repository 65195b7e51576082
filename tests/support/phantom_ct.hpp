// The paper's robot, and the phantom CT's grid for workflow tests: the geometry the reducer checks
// targets against (it must show every target), without rendering a voxel.
#pragma once

#include <memory>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/phantom.hpp"

namespace ignav::test {

// The paper's robot (configs/robots/torabi2014.yaml), loaded once.
inline std::shared_ptr<const config::Robot> paperRobot() {
  static const auto robot = std::make_shared<const config::Robot>(
      config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml").value());
  return robot;
}

inline std::shared_ptr<const volume::Volume> phantomCtGrid(const config::Robot& robot) {
  auto ct = std::make_shared<volume::Volume>();
  ct->geometry = volume::phantomGeometry(
      registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan)
          .value()
          .spec);
  return ct;
}

}  // namespace ignav::test
