// The paper's robot and the bundled tissue profiles, as every compensation test uses them.
#pragma once

#include <string>

#include "ignav/compensation/compensation.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/config/tissue_profiles.hpp"

namespace ignav::compensation::test {

inline const std::string kConfigs = std::string(IGNAV_SOURCE_DIR) + "/configs/";

// configs/robots/torabi2014.yaml, loaded once.
inline const kinematics::Kinematics& paperRobot() {
  static const auto robot = config::loadRobot(kConfigs + "robots/torabi2014.yaml").value();
  return robot.kinematics;
}

// A configs/tissues.yaml profile (agar, plastisol, none), the stylet carried rigidly.
inline DeflectionModel profile(const std::string& name) {
  const auto p =
      config::tissueProfile(config::loadTissueProfiles(kConfigs + "tissues.yaml").value(), name);
  return {p->needle, p->tissue, StyletCarry::kRotated};
}

}  // namespace ignav::compensation::test
