// The confirmation CT's registration: reused when the markers stayed, made anew when they moved
// (the new one checked against the transform the markers were moved by), refused when they are
// far off or missing.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "ignav/verification/confirmation_registration.hpp"

namespace ignav::verification {
namespace {

using registration::TransformKind;

// The paper robot's three feature points (robot frame, mm), roughly: base, cannula tip, stylet.
const std::vector<Eigen::Vector3d> kModel = {{0, 0, -95}, {0, 0, -160}, {18, 0, -190}};

// Image = rigid motion of the model: a rotation about a tilted axis and a shift.
Eigen::Isometry3d robotToImage() {
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.rotate(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 0.4, 0.2).normalized()));
  m.pretranslate(Eigen::Vector3d(12, -40, 150));
  return m;
}

std::vector<Eigen::Vector3d> imageOf(const Eigen::Isometry3d& robot_to_image) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : kModel)
    out.push_back(robot_to_image * p);
  return out;
}

registration::Registration planningRegistration() {
  auto reg =
      registration::registerPoints(imageOf(robotToImage()), kModel, TransformKind::kRigid, {});
  EXPECT_TRUE(reg) << reg.error().message;
  return reg.value();
}

TEST(ConfirmationRegistration, MarkersWhereTheyWereReuseTheSessionsRegistration) {
  const auto planning = planningRegistration();
  auto markers = imageOf(robotToImage());
  markers[1] += Eigen::Vector3d(0.3, -0.2, 0.1);  // localisation noise
  const auto got = registerConfirmation(planning, markers, kModel, TransformKind::kRigid, {});
  ASSERT_TRUE(got) << got.error().message;
  EXPECT_TRUE(got->reused);
  EXPECT_NEAR(got->marker_shift_mm, std::sqrt(0.09 + 0.04 + 0.01), 1e-9);
  EXPECT_TRUE(got->registration.imageToRobot().isApprox(planning.imageToRobot(), 1e-12));
}

TEST(ConfirmationRegistration, MarkersThatMovedRegisterTheScanAnew) {
  const auto planning = planningRegistration();
  // The patient table moved 6 mm and the robot turned 2° with it: the new scan's frame differs.
  Eigen::Isometry3d moved = Eigen::Isometry3d::Identity();
  moved.rotate(Eigen::AngleAxisd(2.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
  moved.pretranslate(Eigen::Vector3d(6, 0, 0));
  const Eigen::Isometry3d now = moved * robotToImage();
  const auto got = registerConfirmation(planning, imageOf(now), kModel, TransformKind::kRigid, {});
  ASSERT_TRUE(got) << got.error().message;
  EXPECT_FALSE(got->reused);
  EXPECT_GT(got->marker_shift_mm, 6.0);
  // The new registration is the inverse of the motion that made the scan, to rounding.
  EXPECT_TRUE(got->registration.imageToRobot().isApprox(now.inverse().matrix(), 1e-9))
      << got->registration.imageToRobot();
  EXPECT_LT(got->registration.fre_mm, 1e-9);
}

TEST(ConfirmationRegistration, MarkersFarOffOrMissingAreRefusedWithTheReason) {
  const auto planning = planningRegistration();
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.pretranslate(Eigen::Vector3d(0, 45, 0));
  const auto off = registerConfirmation(planning, imageOf(far * robotToImage()), kModel,
                                        TransformKind::kRigid, {});
  ASSERT_FALSE(off);
  EXPECT_EQ(off.error().reason, "markers_far_off");
  EXPECT_NE(off.error().message.find("45.0 mm"), std::string::npos) << off.error().message;

  auto two = imageOf(robotToImage());
  two.pop_back();
  const auto missing = registerConfirmation(planning, two, kModel, TransformKind::kRigid, {});
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("2 of the robot's 3 markers"), std::string::npos)
      << missing.error().message;
}

TEST(ConfirmationRegistration, MarkersThatNoLongerFitTheRobotAreRefused) {
  const auto planning = planningRegistration();
  auto bent = imageOf(robotToImage());
  // The stylet's marker 8 mm farther from the base's than the robot allows: no rigid motion
  // of the robot puts its markers there (FRE over the 1.5 mm limit).
  bent[2] += 8.0 * (bent[2] - bent[0]).normalized();
  const auto got = registerConfirmation(planning, bent, kModel, TransformKind::kRigid, {});
  ASSERT_FALSE(got);
  EXPECT_NE(got.error().message.find("do not register"), std::string::npos) << got.error().message;
}

}  // namespace
}  // namespace ignav::verification
