#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "test_instruments.hpp"

namespace ignav::kinematics {
namespace {

constexpr double kPi = 3.14159265358979323846;
using testing::paperInstrument;

TEST(Paper, ExitAngleIs11_4Deg) {
  const auto k = Kinematics::create(paperInstrument()).value();
  const double phi_deg = k.exitAngle_rad() * 180.0 / kPi;
  EXPECT_NEAR(phi_deg, 11.4, 0.05);      // the paper prints 11.4°
  EXPECT_NEAR(phi_deg, 11.397, 0.0005);  // MODEL.md §4
}

TEST(Paper, ExitErrorEPhi) {
  // MODEL.md §4: eϕ = 7.530 mm with the paper's numbers (the paper prints 7.6, ~1 % off).
  const auto w = Kinematics::create(paperInstrument()).value().workspace();
  EXPECT_NEAR(w.exit_error_mm, 7.530, 0.0005);
  EXPECT_NEAR(w.exit_error_mm, 7.6, 0.08);
}

TEST(Forward, TipAtHomeAndFullyDeployedMatchModelFigures) {
  // Figures computed independently in MODEL.md §3 for Rd = 550, z_fixed = 95, lateral offset.
  const auto k = Kinematics::create(paperInstrument()).value();
  const TipPose home = k.forward({0.0, 0.0, 0.0});
  EXPECT_NEAR(home.tip_mm.x(), 0.0, 1e-12);
  EXPECT_NEAR(home.tip_mm.y(), 1.8030, 5e-5);
  EXPECT_NEAR(home.tip_mm.z(), -134.939, 5e-4);
  const TipPose deep = k.forward({0.0, 40.0, 40.0});
  EXPECT_NEAR(deep.tip_mm.y(), 26.5351, 5e-5);
  EXPECT_NEAR(deep.tip_mm.z(), -202.424, 5e-4);
}

TEST(Forward, RotationIsRightHandedAboutPlusZ) {
  // p = Rz(θc)(0, y', z'): at θc = 90° the bend points to -X.
  const auto k = Kinematics::create(paperInstrument()).value();
  const TipPose a = k.forward({0.0, 10.0, 20.0});
  const TipPose b = k.forward({kPi / 2, 10.0, 20.0});
  EXPECT_NEAR(b.tip_mm.x(), -a.tip_mm.y(), 1e-12);
  EXPECT_NEAR(b.tip_mm.y(), 0.0, 1e-12);
  EXPECT_NEAR(b.tip_mm.z(), a.tip_mm.z(), 1e-12);
}

// An independent model of the instrument's shape: march a moving frame along the centreline in
// 3-D (straight cannula, deflected cannula arc, exit offset, exit tilt ϕ, stylet arc), rotating
// the frame step by step. Shares no formula with forward() beyond the geometry's definition.
struct Marched {
  Eigen::Vector3d cannula_tip, tip;
  double approach_rad;
  double cannula_length;
};

Marched march(const Instrument& g, const Joints& j, double step_mm) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Vector3d t(0, 0, -1);  // tangent
  Eigen::Vector3d n = Eigen::AngleAxisd(j.theta_c_rad, Eigen::Vector3d::UnitZ()) *
                      Eigen::Vector3d::UnitY();  // bend side
  const Eigen::Vector3d axis = t.cross(n);       // bending turns t towards n about this axis
  double length = 0.0;
  auto arc = [&](double len, double curvature) {
    const int steps = std::max(1, static_cast<int>(std::ceil(len / step_mm)));
    const double h = len / steps;
    const Eigen::AngleAxisd half(0.5 * h * curvature, axis);
    for (int i = 0; i < steps; ++i) {
      t = half * t;  // Strang splitting: half turn, advance, half turn
      n = half * n;
      p += h * t;
      t = half * t;
      n = half * n;
      length += h;
    }
  };
  const double clearance = 0.5 * (g.cannula_inner_diameter_mm - g.stylet_outer_diameter_mm);
  const double phi = std::acos(1.0 - 2.0 * clearance / g.stylet_radius_mm);
  const double deflected = g.stylet_curved_length_mm - j.z_s_mm;
  const double cannula_total = g.cannula_fixed_offset_mm + g.stylet_travel_mm + j.z_c_mm;
  arc(cannula_total - deflected, 0.0);
  arc(deflected,
      std::isinf(g.cannula_deflected_radius_mm) ? 0.0 : 1.0 / g.cannula_deflected_radius_mm);
  Marched m;
  m.cannula_tip = p;
  m.cannula_length = length;
  if (g.exit_offset == ExitOffset::kLateral) p += clearance * n;  // out through the lip
  if (g.exit_offset == ExitOffset::kAxial) p += clearance * t;
  const Eigen::AngleAxisd tilt(phi, axis);
  t = tilt * t;
  n = tilt * n;
  arc(j.z_s_mm, 1.0 / g.stylet_radius_mm);
  m.tip = p;
  m.approach_rad = std::acos(std::clamp(-t.z(), -1.0, 1.0));
  return m;
}

TEST(Forward, AgreesWithFrameMarchingIntegration) {
  std::mt19937_64 rng(7);
  for (const auto& named : testing::variedInstruments()) {
    const auto k = Kinematics::create(named.instrument).value();
    const Instrument& g = named.instrument;
    std::uniform_real_distribution<double> theta(0.0, 2 * kPi), zc(0.0, g.cannula_travel_mm),
        zs(0.0, g.stylet_travel_mm);
    for (int i = 0; i < 20; ++i) {
      const Joints j{theta(rng), zc(rng), zs(rng)};
      const TipPose pose = k.forward(j);
      const Marched m = march(g, j, 0.005);
      EXPECT_LT((pose.tip_mm - m.tip).norm(), 1e-6) << named.name;
      EXPECT_LT((pose.cannula_tip_mm - m.cannula_tip).norm(), 1e-6) << named.name;
      EXPECT_NEAR(pose.approach_rad, m.approach_rad, 1e-9) << named.name;
    }
  }
}

TEST(Forward, CannulaLengthIsPreservedAsTheStyletDeploys) {
  // The cannula's arc length from P0 to its tip is z_fixed + zs_max + zc whatever zs is
  // (MODEL.md §3): its tip slides along the deflected arc, it does not stretch.
  const Instrument g = paperInstrument();
  const auto k = Kinematics::create(g).value();
  for (double zs : {0.0, 10.0, 25.0, 40.0}) {
    const Marched m = march(g, {0.3, 12.0, zs}, 0.01);
    EXPECT_NEAR(m.cannula_length, g.cannula_fixed_offset_mm + g.stylet_travel_mm + 12.0, 1e-9);
    EXPECT_LT((k.forward({0.3, 12.0, zs}).cannula_tip_mm - m.cannula_tip).norm(), 1e-6);
  }
}

TEST(Forward, TipGoesDeeperAsTheStyletDeploys) {
  // The sign restored in eq (8): deploying the stylet moves the tip into the body (more -z).
  const auto k = Kinematics::create(paperInstrument()).value();
  double previous = k.forward({0, 0, 0}).tip_mm.z();
  for (double zs = 1.0; zs <= 40.0; zs += 1.0) {
    const double z = k.forward({0, 0, zs}).tip_mm.z();
    EXPECT_LT(z, previous) << zs;
    previous = z;
  }
}

TEST(Forward, JointRangesAreChecked) {
  const auto k = Kinematics::create(paperInstrument()).value();
  EXPECT_TRUE(k.checkJoints({1.0, 40.0, 0.0}).ok());
  const auto deep = k.checkJoints({0.0, 41.0, 0.0});
  ASSERT_FALSE(deep.ok());
  EXPECT_NE(deep.error().message.find("z_c_mm"), std::string::npos) << deep.error().message;
  EXPECT_FALSE(k.checkJoints({0.0, 0.0, -0.1}).ok());
  EXPECT_FALSE(k.checkJoints({NAN, 0.0, 0.0}).ok());
}

}  // namespace
}  // namespace ignav::kinematics
