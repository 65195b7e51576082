#include "ignav/registration/robot_phantom.hpp"

#include <cmath>

#include <Eigen/Geometry>

namespace ignav::registration {

Expected<RobotPhantom> makeRobotPhantom(const kinematics::Kinematics& kinematics,
                                        const ScanSetup& setup, const RobotPhantomPose& pose) {
  auto model = featurePoints(kinematics, setup);
  if (!model) return model.error();
  if (!std::isfinite(pose.tilt_deg) || !pose.tilt_axis_lps.allFinite() ||
      pose.tilt_axis_lps.norm() == 0.0) {
    return makeError(ErrorCode::kInvalidArgument,
                     "robot phantom: tilt_deg and a non-zero finite tilt_axis_lps are required");
  }
  const auto& instrument = kinematics.instrument();
  Eigen::Vector3d centre = pose.grid_centre_robot_mm;
  if (!centre.allFinite()) {
    const double deepest =
        kinematics.forward({0.0, instrument.cannula_travel_mm, instrument.stylet_travel_mm})
            .tip_mm.z();
    const double top = (*model)[static_cast<int>(FeaturePoint::kCannulaBase)].z();
    centre = Eigen::Vector3d(0.0, 0.0, 0.5 * (top + deepest));
  }
  // robot -> image: rotate about the centre, which lands on the grid centre.
  const Eigen::Matrix3d rotation =
      Eigen::AngleAxisd(pose.tilt_deg * M_PI / 180.0, pose.tilt_axis_lps.normalized())
          .toRotationMatrix();
  RobotPhantom phantom;
  phantom.model_robot_mm = *model;
  Eigen::Matrix4d robot_to_image = Eigen::Matrix4d::Identity();
  robot_to_image.topLeftCorner<3, 3>() = rotation;
  robot_to_image.topRightCorner<3, 1>() = -rotation * centre;
  phantom.image_to_robot_true = robot_to_image.inverse();

  // Big enough for the markers and the feasible volume, at a typical CT resolution.
  auto& spec = phantom.spec;
  spec.dims = {128, 128, 112};
  spec.spacing_mm = Eigen::Vector3d(0.8, 0.8, 1.25);
  spec.box_half_extent_mm = Eigen::Vector3d(46.0, 46.0, 64.0);
  spec.fiducials_lps_mm.clear();
  for (const auto& p : *model) {
    spec.fiducials_lps_mm.push_back(rotation * (p - centre));
  }
  return phantom;
}

}  // namespace ignav::registration
