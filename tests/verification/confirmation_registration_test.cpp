// The confirmation CT's registration: reused when the markers stayed, made anew when they moved
// (the new one checked against the transform the markers were moved by), refused when they are
// far off or missing.
#include <gtest/gtest.h>

#include <random>
#include <utility>

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

// Markers found with localisation noise: SD `sd_mm` per axis (0.03: 0.05 mm RMS in 3-D, what
// our detection achieves on the phantom's scans, docs/VERIFICATION.md).
std::vector<Eigen::Vector3d> foundWithNoise(const Eigen::Isometry3d& robot_to_image, double sd_mm,
                                            unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sd_mm);
  auto out = imageOf(robot_to_image);
  for (auto& p : out)
    p += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  return out;
}

TEST(ConfirmationRegistration, ACommonMotionOfAFewTenthsIsMotionNotNoise) {
  // Issue 40: the robot and the patient moved together by 0.81 mm, or turned 0.6° about the
  // robot's base; the markers are found to 0.05 mm. The move must be seen (the scan registered
  // anew), so that a seed is measured against where the robot now is. A seed 20 mm past the
  // stylet marker (robot frame) lies exactly at its planned place: the error must say ~0.
  const Eigen::Vector3d seed_robot(25, 3, -205);
  Eigen::Isometry3d shifted = Eigen::Isometry3d::Identity();
  shifted.pretranslate(Eigen::Vector3d(0.47, -0.38, 0.55));  // 0.81 mm
  Eigen::Isometry3d turned = Eigen::Isometry3d::Identity();
  turned.translate(robotToImage() * Eigen::Vector3d(0, 0, -95));
  turned.rotate(Eigen::AngleAxisd(0.6 * M_PI / 180.0, Eigen::Vector3d(0.3, 1, 0).normalized()));
  turned.translate(-(robotToImage() * Eigen::Vector3d(0, 0, -95)));
  for (unsigned seed = 1; seed <= 10; ++seed) {
    auto planned = registration::registerPoints(foundWithNoise(robotToImage(), 0.03, seed), kModel,
                                                TransformKind::kRigid, {});
    ASSERT_TRUE(planned) << planned.error().message;
    for (const auto& [motion, what] :
         {std::pair{shifted, "shifted 0.81 mm"}, std::pair{turned, "turned 0.6°"}}) {
      const Eigen::Isometry3d now = motion * robotToImage();
      const auto got = registerConfirmation(*planned, foundWithNoise(now, 0.03, 100 + seed), kModel,
                                            TransformKind::kRigid, {});
      ASSERT_TRUE(got) << got.error().message;
      EXPECT_FALSE(got->reused) << what << ", seed " << seed << ": " << got->message;
      const double error_mm = (got->registration.toRobot(now * seed_robot) - seed_robot).norm();
      EXPECT_LT(error_mm, 0.25) << what << ", seed " << seed << ": " << got->message;
      EXPECT_NE(got->message.find("more than their localisation explains"), std::string::npos)
          << got->message;
    }
  }
}

TEST(ConfirmationRegistration, NoiseAloneReusesTheSessionsRegistrationAndSaysWhy) {
  // The same markers found twice with 0.05 mm of localisation noise, nothing moved: reused
  // every time, and the message gives the limit it was judged by.
  for (unsigned seed = 1; seed <= 20; ++seed) {
    auto planned = registration::registerPoints(foundWithNoise(robotToImage(), 0.03, seed), kModel,
                                                TransformKind::kRigid, {});
    ASSERT_TRUE(planned) << planned.error().message;
    const auto got = registerConfirmation(*planned, foundWithNoise(robotToImage(), 0.03, 50 + seed),
                                          kModel, TransformKind::kRigid, {});
    ASSERT_TRUE(got) << got.error().message;
    EXPECT_TRUE(got->reused) << "seed " << seed << ": " << got->message;
    EXPECT_GE(got->planning_localisation_mm, 0.05);
    EXPECT_GT(got->reuse_limit_mm, got->marker_shift_mm);
    EXPECT_NE(got->message.find("within what their localisation explains"), std::string::npos)
        << got->message;
  }
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
