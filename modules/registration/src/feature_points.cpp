#include "ignav/registration/feature_points.hpp"

#include <cmath>

#include <fmt/format.h>

namespace ignav::registration {

const char* toString(FeaturePoint point) {
  switch (point) {
    case FeaturePoint::kCannulaBase:
      return "cannula_base";
    case FeaturePoint::kCannulaTip:
      return "cannula_tip";
    case FeaturePoint::kStyletTip:
      return "stylet_tip";
  }
  return "unknown";
}

Expected<FeaturePoints> featurePoints(const kinematics::Kinematics& kinematics,
                                      const ScanSetup& setup) {
  if (auto ok = kinematics.checkJoints(setup.scan_joints); !ok) {
    return makeError(ErrorCode::kInvalidArgument,
                     "robot.registration.scan_joints: " + ok.error().message);
  }
  const auto& instrument = kinematics.instrument();
  // The cannula is straight from its proximal end down to where the deflected arc starts.
  const double straight_mm = instrument.cannula_fixed_offset_mm + instrument.stylet_travel_mm -
                             instrument.stylet_curved_length_mm;
  if (!std::isfinite(setup.cannula_base_mm) || setup.cannula_base_mm < 0.0 ||
      setup.cannula_base_mm > straight_mm) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("robot.registration.cannula_base_mm = {:g} must lie on the straight "
                    "part of the cannula, [0, {:g}] mm from its proximal end",
                    setup.cannula_base_mm, straight_mm));
  }
  const auto pose = kinematics.forward(setup.scan_joints);
  FeaturePoints points;
  points[static_cast<int>(FeaturePoint::kCannulaBase)] =
      Eigen::Vector3d(0.0, 0.0, -(setup.cannula_base_mm + setup.scan_joints.z_c_mm));
  points[static_cast<int>(FeaturePoint::kCannulaTip)] = pose.cannula_tip_mm;
  points[static_cast<int>(FeaturePoint::kStyletTip)] = pose.tip_mm;
  return points;
}

}  // namespace ignav::registration
