// Insertion planning against closed forms (trapezoidal moves), brute force (orders of small
// plans) and the transmission's absolute step counts.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "ignav/config/robot_config.hpp"
#include "ignav/planning/insertion_plan.hpp"

namespace ignav::planning {
namespace {

using kinematics::Joints;

const config::Robot& robot() {
  static const config::Robot r =
      config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml").value();
  return r;
}

std::vector<PlannedTarget> randomTargets(std::mt19937_64& rng, std::size_t n) {
  std::uniform_real_distribution<double> theta(0.0, 2 * M_PI - 1e-9), z(0.0, 40.0);
  std::vector<PlannedTarget> t;
  for (std::size_t i = 0; i < n; ++i) {
    t.push_back({static_cast<std::uint32_t>(i + 1), {theta(rng), z(rng), z(rng)}});
  }
  return t;
}

TEST(Planning, TrapezoidAndTriangleMoveTimes) {
  const AxisProfile axis{2.0, 8.0};  // reaches 2 mm/s after 0.25 mm
  EXPECT_NEAR(moveDuration_s(10.0, axis), 10.0 / 2.0 + 2.0 / 8.0, 1e-12);
  EXPECT_NEAR(moveDuration_s(-10.0, axis), 5.25, 1e-12);
  EXPECT_NEAR(moveDuration_s(0.1, axis), 2.0 * std::sqrt(0.1 / 8.0), 1e-12);
  EXPECT_NEAR(moveDuration_s(0.5, axis), 0.5 / 2.0 + 0.25, 1e-12);  // exactly the ramps
  EXPECT_NEAR(moveDuration_s(0.5 - 1e-12, axis), 2.0 * std::sqrt(0.5 / 8.0), 1e-6);
  EXPECT_EQ(moveDuration_s(0.0, axis), 0.0);
}

TEST(Planning, OrdersWithinOneTurnFromHome) {
  std::mt19937_64 rng(5);
  const auto targets = randomTargets(rng, 100);
  const auto o = orderTargets(targets, {}, PlanningLimits{});
  ASSERT_EQ(o.order.size(), 100u);
  EXPECT_LE(o.total_rotation_rad, 2 * M_PI);
  // From θc = 0 no order rotates less than the largest θc.
  double largest = 0.0;
  for (const auto& t : targets)
    largest = std::max(largest, t.joints.theta_c_rad);
  EXPECT_GE(o.total_rotation_rad, largest - 1e-12);
  // Local search never loses to the plain θc sweep it starts from.
  std::vector<std::size_t> sweep(targets.size());
  std::iota(sweep.begin(), sweep.end(), std::size_t{0});
  std::sort(sweep.begin(), sweep.end(), [&](auto a, auto b) {
    return targets[a].joints.theta_c_rad < targets[b].joints.theta_c_rad;
  });
  EXPECT_LE(o.duration_s, evaluateOrder(targets, sweep, {}, PlanningLimits{}).duration_s);
}

double bruteForceOptimum(const std::vector<PlannedTarget>& targets, const Joints& start,
                         const PlanningLimits& limits) {
  std::vector<std::size_t> perm(targets.size());
  std::iota(perm.begin(), perm.end(), std::size_t{0});
  double optimum = INFINITY;
  do {
    const auto o = evaluateOrder(targets, perm, start, limits);
    if (o.total_rotation_rad <= limits.max_total_rotation_rad) {
      optimum = std::min(optimum, o.duration_s);
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
  return optimum;
}

TEST(Planning, SmallPlansAreOptimalAndNineTargetsNearlySo) {
  std::mt19937_64 rng(11);
  PlanningLimits limits;
  // Up to 8 targets every order is tried; from θc = 90° the rotation limit binds for some.
  for (int trial = 0; trial < 10; ++trial) {
    const auto targets = randomTargets(rng, 3 + trial % 6);
    const Joints start{M_PI / 2, 0.0, 0.0};
    const auto o = orderTargets(targets, start, limits);
    const double optimum = bruteForceOptimum(targets, start, limits);
    if (std::isinf(optimum)) {  // no order from 90° stays within one turn
      EXPECT_GT(o.total_rotation_rad, limits.max_total_rotation_rad);
      continue;
    }
    EXPECT_LE(o.total_rotation_rad, limits.max_total_rotation_rad + 1e-12);
    EXPECT_NEAR(o.duration_s, optimum, 1e-9);
  }
  // At 9 targets the local search: within 3 % of the optimum on each of 4 random plans.
  for (int trial = 0; trial < 4; ++trial) {
    const auto targets = randomTargets(rng, 9);
    const auto o = orderTargets(targets, {}, limits);
    const double optimum = bruteForceOptimum(targets, {}, limits);
    EXPECT_LE(o.total_rotation_rad, limits.max_total_rotation_rad);
    EXPECT_LE(o.duration_s, optimum * 1.03) << "trial " << trial;
  }
}

TEST(Planning, MovesFollowTheMechanismAndTheirStepsAddUp) {
  std::mt19937_64 rng(3);
  const auto targets = randomTargets(rng, 12);
  auto plan =
      planInsertion(robot().kinematics, robot().transmission, targets, {}, PlanningLimits{});
  ASSERT_TRUE(plan.ok()) << plan.error().message;
  ASSERT_EQ(plan->motions.size(), targets.size());
  std::array<std::int64_t, 3> total{0, 0, 0};
  double duration = 0.0;
  Joints at{};
  for (const auto& motion : plan->motions) {
    const auto& goal = std::find_if(targets.begin(), targets.end(), [&](const auto& t) {
                         return t.id == motion.target_id;
                       })->joints;
    MoveKind last = MoveKind::kRetractStylet;
    for (const auto& m : motion.moves) {
      EXPECT_GE(static_cast<int>(m.kind), static_cast<int>(last));  // the paper's sequence
      last = m.kind;
      EXPECT_TRUE(robot().kinematics.checkJoints(m.to).ok());
      for (int a = 0; a < 3; ++a)
        total[a] += m.steps.motor[a];
      duration += m.duration_s;
      at = m.to;
    }
    EXPECT_NEAR(at.theta_c_rad, goal.theta_c_rad, 1e-12);
    EXPECT_NEAR(at.z_c_mm, goal.z_c_mm, 1e-12);
    EXPECT_NEAR(at.z_s_mm, goal.z_s_mm, 1e-12);
  }
  for (int a = 0; a < 3; ++a)
    total[a] += plan->final_retract.steps.motor[a];
  duration += plan->final_retract.duration_s;
  // Increments of quantised absolute poses: they add up to the last pose's absolute steps.
  Joints home = at;
  home.z_s_mm = 0.0;
  const auto absolute = robot().transmission.toSteps(home).steps;
  EXPECT_EQ(total, absolute.motor);
  EXPECT_NEAR(duration, plan->duration_s, 1e-9);
}

TEST(Planning, RefusesWhatCannotBePlanned) {
  const auto& k = robot().kinematics;
  const auto& tx = robot().transmission;
  PlanningLimits limits;
  auto message = [&](const std::vector<PlannedTarget>& t, const Joints& start,
                     const PlanningLimits& l) {
    auto p = planInsertion(k, tx, t, start, l);
    EXPECT_FALSE(p.ok());
    return p.ok() ? std::string() : p.error().message;
  };
  EXPECT_NE(message({}, {}, limits).find("no targets"), std::string::npos);
  std::vector<PlannedTarget> many;
  for (std::uint32_t i = 0; i < 101; ++i)
    many.push_back({i, {0.1, 1.0, 1.0}});
  EXPECT_NE(message(many, {}, limits).find("101 targets; one insertion takes at most 100"),
            std::string::npos);
  EXPECT_NE(
      message({{7, {0.1, 1, 1}}, {7, {0.2, 1, 1}}}, {}, limits).find("target 7 appears twice"),
      std::string::npos);
  EXPECT_NE(message({{3, {0.1, 41.0, 1}}}, {}, limits)
                .find("target 3: z_c_mm = 41 is outside the cannula travel"),
            std::string::npos);
  PlanningLimits stopped = limits;
  stopped.z_c.speed = 0.0;
  EXPECT_NE(message({{1, {0.1, 1, 1}}}, {}, stopped).find("z_c: speed 0"), std::string::npos);
  // From θc = 180°, targets at 1° and 359°: any order turns at least 179° + 358° > 360°.
  const double deg = M_PI / 180.0;
  auto p = planInsertion(k, tx, {{1, {1 * deg, 5, 5}}, {2, {359 * deg, 5, 5}}}, {180 * deg, 0, 0},
                         limits);
  ASSERT_FALSE(p.ok());
  EXPECT_EQ(p.error().reason, "rotation_limit");
  EXPECT_NE(p.error().message.find("537.0°"), std::string::npos) << p.error().message;
}

}  // namespace
}  // namespace ignav::planning
