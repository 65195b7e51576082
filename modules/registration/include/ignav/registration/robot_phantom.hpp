// The built-in phantom with the robot in it: bead markers at the robot's three feature points
// (scan-time joints), the robot inclined in the scanner as in the paper's experiments (§VI),
// and a gelatin box around the feasible volume. The true image -> robot transform is known, so
// detection, registration and targeting can be checked end to end.
#pragma once

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/kinematics/solver.hpp"
#include "ignav/registration/feature_points.hpp"
#include "ignav/volume/phantom.hpp"

namespace ignav::registration {

struct RobotPhantomPose {
  // The robot frame is inclined by this rotation (axis in LPS, need not be unit) ...
  double tilt_deg = 18.0;
  Eigen::Vector3d tilt_axis_lps{1.0, 0.4, 0.0};
  // ... and the grid centre (LPS 0,0,0) sits at this robot-frame point (mid-way between the
  // base marker and the deepest reachable tip when left NaN).
  Eigen::Vector3d grid_centre_robot_mm{std::nan(""), std::nan(""), std::nan("")};
};

struct RobotPhantom {
  volume::PhantomSpec spec;             // fiducials_lps_mm = markers in model order
  FeaturePoints model_robot_mm;         // the feature points in the robot frame
  Eigen::Matrix4d image_to_robot_true;  // rigid, scale 1
};

Expected<RobotPhantom> makeRobotPhantom(const kinematics::Kinematics& kinematics,
                                        const ScanSetup& setup, const RobotPhantomPose& pose = {});

}  // namespace ignav::registration
