// The three feature points the paper registers with (§IV: base of the cannula, tip of the
// cannula, tip of the stylet), in the robot frame, from the kinematics at the joints the robot
// held during the scan. The paper scans with the stylet fully deployed, which is what makes the
// three points non-collinear: base and cannula tip lie on the axis.
#pragma once

#include <array>
#include <string>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/kinematics/instrument.hpp"
#include "ignav/kinematics/solver.hpp"

namespace ignav::registration {

struct ScanSetup {
  kinematics::Joints scan_joints{0.0, 0.0, 40.0};  // stylet fully deployed
  // Where the base feature sits on the cannula's straight part: this far along -Z from the
  // cannula's proximal end (P0 at z_c = 0), moving with z_c like the cannula itself.
  double cannula_base_mm = 95.0;
};

enum class FeaturePoint { kCannulaBase = 0, kCannulaTip = 1, kStyletTip = 2 };
const char* toString(FeaturePoint point);  // "cannula_base" | "cannula_tip" | "stylet_tip"

using FeaturePoints = std::array<Eigen::Vector3d, 3>;  // indexed by FeaturePoint

// Errors when the scan joints are outside their ranges or the base feature is not on the
// straight part of the cannula ([0, z_fixed + zs_max - L0]).
Expected<FeaturePoints> featurePoints(const kinematics::Kinematics& kinematics,
                                      const ScanSetup& setup);

}  // namespace ignav::registration
