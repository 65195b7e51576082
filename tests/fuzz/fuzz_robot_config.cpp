// The robot YAML (geometry, transmission, limits, registration settings): parsed, then turned
// into a robot whose kinematics must answer for its own home pose.
#include <cmath>
#include <string>

#include "ignav/config/robot_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto config = ignav::config::parseRobotConfig(text, "fuzz.yaml");
  if (!config.ok()) return 0;
  auto robot = ignav::config::makeRobot(*config, "fuzz.yaml");
  if (!robot.ok()) return 0;
  // A robot the loader accepts has finite kinematics at its home pose.
  const auto tip = robot->kinematics.forward(ignav::kinematics::Joints{}).tip_mm;
  if (!std::isfinite(tip.x()) || !std::isfinite(tip.y()) || !std::isfinite(tip.z()))
    __builtin_trap();
  return 0;
}
