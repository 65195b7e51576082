// The robot configuration file (configs/robots/*.yaml): geometry, transmission and limits.
// Every error names the file and the YAML key path, e.g.
//   "configs/robots/x.yaml: robot.stylet.radius_mm: must be positive (got -3)".
#pragma once

#include <string>

#include "ignav/actuation/transmission.hpp"
#include "ignav/core/expected.hpp"
#include "ignav/kinematics/instrument.hpp"
#include "ignav/kinematics/solver.hpp"
#include "ignav/registration/settings.hpp"

namespace ignav::config {

struct RobotConfig {
  std::string name;
  kinematics::Instrument instrument;
  actuation::TransmissionSpec transmission;
  registration::RegistrationSettings registration;  // optional section; defaults otherwise
};

// Parses and validates (unknown keys are errors: a misspelt key must not silently fall back to
// a default). `source` names the document in messages.
Expected<RobotConfig> parseRobotConfig(const std::string& yaml_text, const std::string& source);
Expected<RobotConfig> loadRobotConfig(const std::string& path);

// A validated robot, ready to use: the config with its kinematics and transmission built.
struct Robot {
  RobotConfig config;
  kinematics::Kinematics kinematics;
  actuation::Transmission transmission;
  // The registration feature points in the robot frame at the scan-time joints.
  registration::FeaturePoints feature_points_mm;
};

Expected<Robot> loadRobot(const std::string& path);
Expected<Robot> makeRobot(const RobotConfig& config, const std::string& source);

}  // namespace ignav::config
