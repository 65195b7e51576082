#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "ignav/actuation/transmission.hpp"
#include "ignav/config/robot_config.hpp"

namespace ignav::actuation {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

Transmission paperTransmission() {
  const auto c =
      config::loadRobotConfig(std::string(IGNAV_SOURCE_DIR) + "/configs/robots/torabi2014.yaml");
  return Transmission::create(c->transmission).value();
}

TEST(Paper, CannulaStepIs18_32Deg) {
  // "each motor step rotates the cannula by 18/32 degrees" (18° step, 16:1 gearhead, 2:1 spur)
  const Transmission t = paperTransmission();
  EXPECT_NEAR(1.0 / t.cannulaStepsPerDeg(), 18.0 / 32.0, 1e-15);
  EXPECT_NEAR(1.0 / t.styletStepsPerDeg(), 0.6, 1e-15);
}

TEST(Paper, StepsPerMillimetre) {
  // MODEL.md §8: 640 / 1.5875 and 600 / 1.5875 steps per mm of screw travel.
  const Transmission t = paperTransmission();
  EXPECT_NEAR(t.cannulaStepsPerMm(), 403.150, 5e-4);
  EXPECT_NEAR(t.styletStepsPerMm(), 377.953, 5e-4);
}

TEST(Coupling, PureMotionsTurnTheRightMotors) {
  const Transmission t = paperTransmission();
  // 1 mm of cannula translation: the threaded nut turns, the spline nut holds, and the stylet
  // nut follows so the stylet keeps its deployment.
  auto s = t.toSteps({0.0, 1.0, 0.0});
  EXPECT_EQ(s.steps, (Steps{{403, 0, 378}}));
  // 1 mm of stylet: only the stylet motor.
  s = t.toSteps({0.0, 0.0, 1.0});
  EXPECT_EQ(s.steps, (Steps{{0, 0, 378}}));
  // 9° of rotation is a whole number of steps on every motor (16 cannula, 15 stylet).
  s = t.toSteps({9.0 * kDeg, 0.0, 0.0});
  EXPECT_EQ(s.steps, (Steps{{16, 16, 15}}));
  EXPECT_NEAR(s.residual.z_s_mm, 0.0, 1e-12);
}

TEST(Coupling, CarriedStyletNutIgnoresRotationAndCannula) {
  TransmissionSpec spec;
  spec.coupling = Coupling::kCarried;
  const Transmission t = Transmission::create(spec).value();
  EXPECT_EQ(t.toSteps({9.0 * kDeg, 1.0, 0.0}).steps.motor[2], 0);
  EXPECT_EQ(t.toSteps({0.0, 0.0, 1.0}).steps.motor[2], 378);
}

TEST(Quantisation, PureRotationLeavesAtMostOnePointThreeMicrometresOfStylet) {
  // The cannula quantum (0.5625°) and the stylet-nut quantum (0.6°) coincide only every 9°, so
  // a rotation leaves a small stylet residual (MODEL.md §8: at most 1.3 µm).
  const Transmission t = paperTransmission();
  double worst = 0.0;
  for (double deg = 0.0; deg <= 360.0; deg += 0.05) {
    const auto s = t.toSteps({deg * kDeg, 0.0, 0.0});
    worst = std::max(worst, std::abs(s.residual.z_s_mm));
    EXPECT_NEAR(s.residual.z_c_mm, 0.0, 1e-12);
    EXPECT_LE(std::abs(s.residual.theta_c_rad), 0.5 / t.cannulaStepsPerDeg() * kDeg + 1e-15);
  }
  EXPECT_LE(worst, 1.33e-3);
  EXPECT_GT(worst, 1.0e-3);
}

TEST(Quantisation, RoundsHalfAwayFromZero) {
  // A transmission with binary-exact step sizes: 20 steps per mm on the stylet nut.
  TransmissionSpec spec;
  spec.motor_step_deg = 18.0;
  spec.gearhead_ratio = 1.0;
  spec.cannula_gear_ratio = 1.0;
  spec.stylet_gear_ratio = 1.0;
  spec.lead_mm = 1.0;
  spec.coupling = Coupling::kCarried;
  const Transmission t = Transmission::create(spec).value();
  EXPECT_EQ(t.toSteps({0.0, 0.0, 0.125}).steps.motor[2], 3);    // 2.5 -> 3
  EXPECT_EQ(t.toSteps({0.0, 0.0, -0.125}).steps.motor[2], -3);  // -2.5 -> -3
  EXPECT_EQ(t.toSteps({0.0, 0.0, 0.075}).steps.motor[2], 2);    // 1.5 -> 2
}

TEST(Quantisation, FeedbackInvertsAndMovesDoNotDrift) {
  const Transmission t = paperTransmission();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> theta(0.0, 2 * kPi), z(0.0, 40.0);
  Joints at{0.0, 0.0, 0.0};
  Steps position;
  for (int i = 0; i < 500; ++i) {
    const Joints next{theta(rng), z(rng), z(rng)};
    const auto move = t.move(at, next);
    for (size_t m = 0; m < 3; ++m)
      position.motor[m] += move.steps.motor[m];
    at = next;
    // The accumulated increments equal the absolute quantisation of the latest target.
    ASSERT_EQ(position, t.toSteps(next).steps);
    const Joints fed_back = t.toJoints(position);
    EXPECT_NEAR(fed_back.z_c_mm, next.z_c_mm, 0.5 / t.cannulaStepsPerMm() + 1e-12);
    EXPECT_NEAR(fed_back.theta_c_rad, next.theta_c_rad, 0.5 / t.cannulaStepsPerDeg() * kDeg);
    EXPECT_NEAR(fed_back.z_s_mm, next.z_s_mm, 0.5 / t.styletStepsPerMm() + 1e-12);
  }
}

TEST(Spec, ErrorsNameTheKey) {
  TransmissionSpec spec;
  spec.microsteps = 0;
  auto t = Transmission::create(spec);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.error().message.find("robot.transmission.microsteps"), std::string::npos);
  spec = TransmissionSpec{};
  spec.lead_mm = NAN;
  t = Transmission::create(spec);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.error().message.find("robot.transmission.lead_mm"), std::string::npos);
}

}  // namespace
}  // namespace ignav::actuation
