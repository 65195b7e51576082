// The deflected landing point against closed forms (the plain bicycle model's circle, a rigid
// stylet turned about the cannula tip, no tissue at all) and against an independent integrator.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "fixtures.hpp"
#include "polyline.hpp"
#include "reference.hpp"

namespace ignav::compensation {
namespace {

using ::ignav::test::distanceToPolyline;
using ::ignav::test::polylineLength;

using test::paperRobot;
using test::profile;

TEST(Landing, PlainBicycleCannulaTipFollowsACircularArc) {
  // λ = 0: the cannula tip runs on the circle of radius 1/|k| tangent to the axis at the entry
  // (its tip at z_c = 0), bending to the stylet's side; after z_c of arc it has turned by |k| z_c.
  const auto& kin = paperRobot();
  for (double k : {-1.0 / 400.0, -1.0 / 150.0}) {
    const DeflectionModel plain{{k, 20.0, -1}, {}, StyletCarry::kRotated};
    for (double theta : {0.0, 0.7, 2.5, 4.0}) {
      for (double zc : {5.0, 20.0, 40.0}) {
        const kinematics::Joints j{theta, zc, 25.0};
        const auto l = predictLanding(kin, plain, j);
        ASSERT_TRUE(l.ok()) << l.error().message;
        const Eigen::Vector3d entry = kin.forward({theta, 0.0, 25.0}).cannula_tip_mm;
        const Eigen::Vector3d u(-std::sin(theta), std::cos(theta), 0.0);
        const Eigen::Vector3d centre = entry + u / std::abs(k);
        EXPECT_NEAR((l->cannula_tip_mm - centre).norm(), 1.0 / std::abs(k), 1e-9);
        // The chord from the entry is 2 sin(|k| zc / 2) / |k|, in the plane of θc.
        EXPECT_NEAR((l->cannula_tip_mm - entry).norm(), 2.0 * std::sin(std::abs(k) * zc / 2) / -k,
                    1e-9);
        EXPECT_NEAR((l->cannula_tip_mm - entry).dot(Eigen::Vector3d(u.y(), -u.x(), 0)), 0.0, 1e-12);
        EXPECT_NEAR(l->drift.heading_rad, std::abs(k) * zc, 1e-12);
        EXPECT_NEAR(l->drift.lateral_mm, (1 - std::cos(k * zc)) / -k, 1e-9);
        // The stylet is carried rigidly: same length from the cannula tip, turned by |k| zc.
        const auto nominal = kin.forward(j);
        const Eigen::Vector3d before = nominal.tip_mm - nominal.cannula_tip_mm;
        const Eigen::Vector3d after = l->tip_mm - l->cannula_tip_mm;
        EXPECT_NEAR(after.norm(), before.norm(), 1e-9);
        EXPECT_NEAR(std::atan2(after.cross(before).norm(), after.dot(before)), std::abs(k) * zc,
                    1e-9);
        // Turned towards the bend: the tip moves outwards, further than the cannula.
        EXPECT_GT((l->tip_mm - nominal.tip_mm).dot(u), l->drift.lateral_mm);
      }
    }
  }
}

TEST(Landing, NoTissueIsTheForwardKinematics) {
  // k = 0, λ = 0: a straight push; the landing is the forward kinematics, exactly.
  const auto& kin = paperRobot();
  const DeflectionModel none{{0.0, 20.0, -1}, {}, StyletCarry::kRotated};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> t(0, 2 * M_PI), c(0, 40), s(0, 40);
  for (int i = 0; i < 100; ++i) {
    const kinematics::Joints j{t(rng), c(rng), s(rng)};
    const auto l = predictLanding(kin, none, j);
    ASSERT_TRUE(l.ok());
    EXPECT_LT((l->tip_mm - kin.forward(j).tip_mm).norm(), 1e-12);
  }
  // Out of tissue (z_c = 0) any tissue leaves the tip where the kinematics put it.
  const auto agar = predictLanding(kin, profile("agar"), {1.0, 0.0, 30.0});
  ASSERT_TRUE(agar.ok());
  EXPECT_EQ(agar->tip_mm, kin.forward({1.0, 0.0, 30.0}).tip_mm);
}

TEST(Landing, AgreesWithAnIndependentIntegratorAndRotation) {
  const auto& kin = paperRobot();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> t(0, 2 * M_PI), c(0, 40), s(0, 40);
  for (const char* name : {"agar", "plastisol"}) {
    for (StyletCarry carry : {StyletCarry::kRotated, StyletCarry::kTranslated}) {
      DeflectionModel m = profile(name);
      m.carry = carry;
      double worst = 0.0;
      for (int i = 0; i < 40; ++i) {
        const kinematics::Joints j{t(rng), c(rng), s(rng)};
        const auto l = predictLanding(kin, m, j);
        ASSERT_TRUE(l.ok());
        worst = std::max(worst, (l->tip_mm - reference::landing(kin, m, j)).norm());
      }
      EXPECT_LT(worst, 1e-8) << name;
    }
  }
}

TEST(Landing, CannulaDriftIsWhatThePlannerLabelsTodayWithItsSign) {
  // evaluate() labels a target with the model's y after z_c inserted (negative for k < 0): the
  // cannula's lateral drift here is its size, towards the stylet's side.
  const DeflectionModel agar = profile("agar");
  for (double zc : {3.0, 17.0, 40.0}) {
    const auto drift = cannulaDrift(agar, zc);
    ASSERT_TRUE(drift.ok());
    const auto e = reference::bicycle(agar.needle, agar.tissue, zc);
    EXPECT_NEAR(drift->lateral_mm, -e.y_mm, 1e-9);
    EXPECT_GT(drift->lateral_mm, 0.0);
    EXPECT_NEAR(drift->shortfall_mm, zc - e.z_mm, 1e-9);
  }
  EXPECT_FALSE(cannulaDrift(agar, std::nan("")).ok());
  EXPECT_FALSE(predictLanding(paperRobot(), agar, {0.0, std::nan(""), 1.0}).ok());
}

TEST(Path, WithoutTissueItIsTheInstrumentsOwnShape) {
  // Closed-form properties of MODEL.md §3, none of which predictPath computes directly: the
  // cannula is P0 + zfixed + zsmax + z_c long whatever z_s is, the stylet leaves it the clearance
  // c away and has z_s of arc out, and the ends are the forward kinematics.
  const auto& kin = paperRobot();
  const auto& g = kin.instrument();
  const double clearance = 0.5 * (g.cannula_inner_diameter_mm - g.stylet_outer_diameter_mm);
  for (const kinematics::Joints& j :
       {kinematics::Joints{2.1, 25.0, 30.0}, kinematics::Joints{0.3, 0.0, 5.0},
        kinematics::Joints{4.0, 40.0, 40.0}}) {
    const auto line = kin.centreline(j, 0.25);
    EXPECT_NEAR(polylineLength(line.cannula_mm),
                g.cannula_fixed_offset_mm + g.stylet_travel_mm + j.z_c_mm, 1e-4);
    EXPECT_NEAR(line.cannula_mm.front().norm(), 0.0, 1e-12);  // P0
    EXPECT_NEAR(polylineLength(line.stylet_mm), j.z_s_mm, 1e-4);
    EXPECT_NEAR((line.stylet_mm.front() - line.cannula_mm.back()).norm(), clearance, 1e-9);
    EXPECT_LT((line.cannula_mm.back() - kin.forward(j).cannula_tip_mm).norm(), 1e-9);
    EXPECT_LT((line.stylet_mm.back() - kin.forward(j).tip_mm).norm(), 1e-9);
    // With no tissue (k = 0, λ = 0: a straight push) predictPath is that shape, cut 10 mm above
    // where the tissue begins.
    const DeflectionModel straight{{0.0, 20.0, -1}, {}, StyletCarry::kRotated};
    const auto path = predictPath(kin, straight, j, 0.25, 10.0);
    ASSERT_TRUE(path.ok()) << path.error().message;
    EXPECT_NEAR(polylineLength(path->cannula_mm), j.z_c_mm + 10.0, 0.25);
    for (const auto& q : path->cannula_mm)
      EXPECT_LT(distanceToPolyline(line.cannula_mm, q), 1e-3);  // the chords' sag
    for (const auto& q : path->stylet_mm)
      EXPECT_LT(distanceToPolyline(line.stylet_mm, q), 1e-3);
  }
}

TEST(Path, InTissueTheCannulaLiesWhereItsTipWent) {
  // At the final pose, the cannula point that entered the tissue when s mm were in is displaced
  // from the instrument's shape as the tip was at s (the independent integrator's cannula drift):
  // at the surface not at all, at the tip by the whole drift (predictLanding's cannula tip).
  const auto& kin = paperRobot();
  for (const char* name : {"agar", "plastisol"}) {
    const DeflectionModel m = profile(name);
    const kinematics::Joints j{0.7, 33.0, 21.0};
    const auto path = predictPath(kin, m, j, 0.25, 10.0);
    ASSERT_TRUE(path.ok()) << path.error().message;
    const auto landing = predictLanding(kin, m, j);
    ASSERT_TRUE(landing.ok());
    EXPECT_EQ(path->cannula_mm.back(), landing->cannula_tip_mm);
    EXPECT_EQ(path->stylet_mm.back(), landing->tip_mm);
    const auto shape = kin.centreline(j, 0.25);
    const double length = shape.cannula_arc_mm.back();
    const Eigen::Vector3d u(-std::sin(j.theta_c_rad), std::cos(j.theta_c_rad), 0.0);
    double worst = 0.0;
    for (std::size_t i = 0; i < shape.cannula_mm.size(); i += 7) {
      const double s = j.z_c_mm - (length - shape.cannula_arc_mm[i]);
      if (s < 0.0 || s > j.z_c_mm) continue;
      const auto end = reference::bicycle(m.needle, m.tissue, s);
      const Eigen::Vector3d expected =
          shape.cannula_mm[i] - end.y_mm * u + Eigen::Vector3d(0, 0, s - end.z_mm);
      worst = std::max(worst, distanceToPolyline(path->cannula_mm, expected));
    }
    EXPECT_LT(worst, 1e-4) << name;
    // The stylet keeps its length.
    EXPECT_NEAR(polylineLength(path->stylet_mm), j.z_s_mm, 1e-3) << name;
  }
}

TEST(Path, BadStepsAreRefused) {
  const auto& kin = paperRobot();
  EXPECT_FALSE(predictPath(kin, profile("agar"), {0, 10, 10}, 0.0).ok());
  EXPECT_FALSE(predictPath(kin, profile("agar"), {0, 10, 10}, std::nan("")).ok());
  EXPECT_FALSE(predictPath(kin, profile("agar"), {0, 10, 10}, 0.5, -1.0).ok());
  EXPECT_FALSE(predictPath(kin, profile("agar"), {0, std::nan(""), 10}).ok());
}

}  // namespace
}  // namespace ignav::compensation
