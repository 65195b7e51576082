// The feature points against MODEL.md's printed forward-kinematics figures.
#include <gtest/gtest.h>

#include <cmath>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/feature_points.hpp"

namespace ignav::registration {
namespace {

config::Robot paperRobot() {
  auto robot = config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml");
  EXPECT_TRUE(robot.ok()) << robot.error().message;
  return std::move(robot).value();
}

TEST(FeaturePoints, PaperScanPoseStyletDeployed) {
  const auto robot = paperRobot();
  const auto& p = robot.feature_points_mm;
  // Base on the axis 95 mm down; the straight cannula's tip at z_fixed + zs_max = 135 mm; the
  // stylet tip at MODEL.md §3's (y', z') for zs = 40: (26.5351, -202.424 + z_c 40).
  EXPECT_LT((p[0] - Eigen::Vector3d(0, 0, -95)).norm(), 1e-12);
  EXPECT_LT((p[1] - Eigen::Vector3d(0, 0, -135)).norm(), 1e-9);
  EXPECT_NEAR(p[2].x(), 0.0, 1e-12);
  EXPECT_NEAR(p[2].y(), 26.5351, 5e-5);
  EXPECT_NEAR(p[2].z(), -162.424, 5e-4);
}

TEST(FeaturePoints, FollowTheScanJoints) {
  const auto robot = paperRobot();
  ScanSetup setup;
  setup.scan_joints = {M_PI / 2, 10.0, 40.0};
  setup.cannula_base_mm = 50.0;
  auto p = featurePoints(robot.kinematics, setup);
  ASSERT_TRUE(p.ok()) << p.error().message;
  EXPECT_LT(((*p)[0] - Eigen::Vector3d(0, 0, -60)).norm(), 1e-12);
  // θc = 90° turns +y' to -x (MODEL.md §2).
  EXPECT_NEAR((*p)[2].x(), -26.5351, 5e-5);
  EXPECT_NEAR((*p)[2].y(), 0.0, 1e-9);
  EXPECT_NEAR((*p)[2].z(), -172.424, 5e-4);
}

TEST(FeaturePoints, RejectBaseOffTheStraightCannulaAndBadJoints) {
  const auto robot = paperRobot();
  ScanSetup setup;
  setup.cannula_base_mm = 96.0;
  auto p = featurePoints(robot.kinematics, setup);
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.error().message.find("robot.registration.cannula_base_mm = 96"), std::string::npos)
      << p.error().message;
  setup = ScanSetup{};
  setup.scan_joints.z_c_mm = 41.0;
  p = featurePoints(robot.kinematics, setup);
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.error().message.find("robot.registration.scan_joints"), std::string::npos)
      << p.error().message;
}

}  // namespace
}  // namespace ignav::registration
