// The rod-in-tissue world: its beam against the cantilever's closed form, the world with its
// physics switched off against the robot's forward kinematics, its luck deterministic, its file.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "ignav/config/robot_config.hpp"
#include "ignav/needle_world/rod_world.hpp"

namespace ignav::needle_world {
namespace {

const std::string kConfigs = std::string(IGNAV_SOURCE_DIR) + "/configs/";

const kinematics::Kinematics& paperRobot() {
  static const auto robot = config::loadRobot(kConfigs + "robots/torabi2014.yaml").value();
  return robot.kinematics;
}

TEST(Beam, WithoutTissueItIsACantilever) {
  // w(L) = F L³ / 3EI, w'(L) = F L² / 2EI (a cantilever with a load at its free end). Finite
  // differences with a central clamp are second order: the error falls 4× when the step halves.
  const std::vector<TissueLayer> air{{"air", 0.0, 0.0}};
  const double ei = 63000.0, force = 0.3;
  for (double length : {7.3, 20.0, 40.0}) {
    const double tip = force * std::pow(length, 3) / (3 * ei);
    const double angle = force * length * length / (2 * ei);
    const auto coarse = pushBeam(ei, force, length, 0.0, 0.5, air);
    const auto fine = pushBeam(ei, force, length, 0.0, 0.25, air);
    const double coarse_error = std::abs(coarse.lateral_mm.back() / tip - 1.0);
    const double fine_error = std::abs(fine.lateral_mm.back() / tip - 1.0);
    EXPECT_LT(coarse_error, 3.0 * std::pow(0.5 / length, 2)) << length;
    EXPECT_NEAR(coarse_error / fine_error, 4.0, 0.1) << length;
    EXPECT_NEAR(coarse.tip_angle_rad / angle, 1.0, 0.01) << length;
    EXPECT_NEAR(coarse.lateral_mm.front(), 0.0, 1e-15);
  }
}

TEST(Beam, TissueHoldsItAndStifferTissueHoldsItMore) {
  const double ei = 63000.0, force = 0.3, length = 40.0;
  const double free = pushBeam(ei, force, length, 0.0, 0.5, {{"air", 0.0, 0.0}}).lateral_mm.back();
  double previous = free;
  for (double k : {0.005, 0.02, 0.08}) {
    const auto beam = pushBeam(ei, force, length, 0.0, 0.5, {{"gel", 0.0, k}});
    // The channel remembers: the deviation grows the deeper it goes, and less in stiffer tissue.
    EXPECT_GT(beam.lateral_mm.back(), 0.0) << k;
    EXPECT_LT(beam.lateral_mm.back(), previous) << k;
    previous = beam.lateral_mm.back();
  }
  // No force, no deviation, whatever the tissue.
  const auto still = pushBeam(ei, 0.0, length, 0.0, 0.5, {{"gel", 0.0, 0.05}});
  for (double w : still.lateral_mm)
    EXPECT_EQ(w, 0.0);
}

// A world with its physics switched off.
RodWorld inert() {
  RodWorld w;
  w.name = "inert";
  w.cannula_tip_force_n = w.stylet_tip_force_n = 0.0;
  w.exit_play_bias = 0.0;
  w.twist_rad_per_mm = w.drag_shortfall_per_mm = 0.0;
  w.rotation_sd_rad = w.backlash_mm = w.exit_play_sd = w.mount_sd_mm = 0.0;
  return w;
}

TEST(RodWorld, WithItsPhysicsOffTheNeedleLandsWhereTheKinematicsSay) {
  const auto& kin = paperRobot();
  for (const kinematics::Joints j :
       {kinematics::Joints{0.3, 20.0, 30.0}, {2.0, 38.0, 5.0}, {4.5, 5.0, 38.0}, {1.0, 0.0, 0.0}}) {
    const auto needle = insertNeedle(inert(), kin, j, 1);
    ASSERT_TRUE(needle) << needle.error().message;
    const auto pose = kin.forward(j);
    EXPECT_LT((needle->tip_mm - pose.tip_mm).norm(), 1e-9);
    EXPECT_LT((needle->cannula_tip_mm - pose.cannula_tip_mm).norm(), 1e-9);
    EXPECT_LT((needle->seed_mm - pose.tip_mm).norm(), 1e-9);
  }
}

TEST(RodWorld, EachEffectMovesTheNeedleAndTheLuckIsTheSameForAnInsertion) {
  const auto& kin = paperRobot();
  const kinematics::Joints j{0.7, 30.0, 30.0};
  const Eigen::Vector3d nominal = kin.forward(j).tip_mm;
  auto moved = [&](const RodWorld& w, std::uint64_t insertion = 1) {
    return (insertNeedle(w, kin, j, insertion)->seed_mm - nominal).norm();
  };
  RodWorld w = inert();
  w.cannula_tip_force_n = 0.3;
  EXPECT_GT(moved(w), 0.05);
  w = inert();
  w.twist_rad_per_mm = 0.001;
  EXPECT_GT(moved(w), 0.05);
  w = inert();
  w.drag_shortfall_per_mm = 0.01;
  EXPECT_NEAR(moved(w), 0.6, 1e-9);  // 1 % of the 60 mm pushed in
  w = inert();
  w.exit_play_bias = 0.5;  // 0.35 mm of play over 15 mm of grip, half of it: 0.67°
  EXPECT_GT(moved(w), 0.2);
  const RodWorld world = loadRodWorld(kConfigs + "worlds/layered_gel.yaml").value();
  EXPECT_EQ(moved(world, 7), moved(world, 7));
  EXPECT_NE(moved(world, 7), moved(world, 8));
}

TEST(RodWorld, TheFileLoadsAndMistakesAreNamed) {
  const auto world = loadRodWorld(kConfigs + "worlds/layered_gel.yaml");
  ASSERT_TRUE(world) << world.error().message;
  EXPECT_EQ(world->name, "layered_gel");
  EXPECT_EQ(world->layers.size(), 4u);
  EXPECT_NEAR(world->twist_rad_per_mm, 0.05 * M_PI / 180, 1e-15);
  const std::string path = ::testing::TempDir() + "/world_bad.yaml";
  auto refused = [&](const std::string& text) {
    std::ofstream(path) << text;
    auto got = loadRodWorld(path);
    EXPECT_FALSE(got);
    return got ? std::string() : got.error().message;
  };
  EXPECT_NE(refused("world:\n  cannula_tip_forse_n: 0.3\n").find("world.cannula_tip_forse_n"),
            std::string::npos);
  EXPECT_NE(refused("world:\n  layers:\n    - {from_depth_mm: 5}\n    - {from_depth_mm: 2}\n")
                .find("must start deeper"),
            std::string::npos);
  EXPECT_NE(refused("world:\n  cannula_stiffness_nmm2: -1\n").find("stiffness"), std::string::npos);
  EXPECT_NE(refused("nothing: 1\n").find("no 'world:' map"), std::string::npos);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace ignav::needle_world
