// Fiducial detection on phantoms whose bead centres are known exactly (the phantom renders
// partial volume analytically), with distractors, and matching by mutual distances.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/fiducial_detection.hpp"
#include "ignav/registration/point_registration.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/phantom.hpp"

namespace ignav::registration {
namespace {

using Points = std::vector<Eigen::Vector3d>;

volume::Volume phantom(const volume::PhantomSpec& spec) {
  auto v = volume::makePhantom(spec);
  EXPECT_TRUE(v.ok()) << v.error().message;
  return std::move(v).value();
}

// Distance from each true centre to the nearest accepted candidate.
std::vector<double> localisationErrors(const FiducialDetection& d, const Points& truth) {
  std::vector<double> errors;
  for (const auto& t : truth) {
    double best = INFINITY;
    for (const auto& c : d.candidates) {
      if (c.rejected.empty()) best = std::min(best, (c.centroid_lps_mm - t).norm());
    }
    errors.push_back(best);
  }
  return errors;
}

std::size_t acceptedCount(const FiducialDetection& d) {
  return static_cast<std::size_t>(std::count_if(d.candidates.begin(), d.candidates.end(),
                                                [](const auto& c) { return c.rejected.empty(); }));
}

TEST(FiducialDetection, PhantomBeadsToAFractionOfAVoxel) {
  for (bool oblique : {false, true}) {
    volume::PhantomSpec spec;
    spec.oblique = oblique;
    const auto v = phantom(spec);
    auto d = findFiducials(v, FiducialSearch{}, {});
    ASSERT_TRUE(d.ok()) << d.error().message;
    ASSERT_EQ(acceptedCount(*d), 3u) << d->summary;
    ASSERT_TRUE(d->match.has_value()) << d->summary;
    for (double e : localisationErrors(*d, spec.fiducials_lps_mm)) {
      EXPECT_LT(e, 0.05) << (oblique ? "oblique" : "axial") << ": " << d->summary;
    }
    EXPECT_NEAR(d->candidates[0].background_hu, spec.box_hu, 1.0);
  }
}

TEST(FiducialDetection, NoisyThickSlicesStillSubVoxel) {
  volume::PhantomSpec spec;
  spec.spacing_mm = {0.9, 0.9, 2.0};
  spec.dims = {84, 84, 40};
  spec.noise_sigma_hu = 25.0;
  spec.oblique = true;
  const auto v = phantom(spec);
  auto d = findFiducials(v, FiducialSearch{}, {});
  ASSERT_TRUE(d.ok()) << d.error().message;
  ASSERT_EQ(acceptedCount(*d), 3u) << d->summary;
  for (double e : localisationErrors(*d, spec.fiducials_lps_mm))
    EXPECT_LT(e, 0.15);
}

TEST(FiducialDetection, DistractorsAreRejectedWithReasons) {
  volume::PhantomSpec spec;
  auto v = phantom(spec);
  // A rod of bone-like material along i and a single bright speck.
  for (int i = 10; i < 60; ++i) {
    for (int dj = 0; dj < 2; ++dj)
      v.voxels[v.index(i, 80 + dj, 50)] = 1900;
  }
  v.voxels[v.index(80, 10, 10)] = 2500;
  auto d = findFiducials(v, FiducialSearch{}, {});
  ASSERT_TRUE(d.ok()) << d.error().message;
  EXPECT_EQ(acceptedCount(*d), 3u) << d->summary;
  std::vector<std::string> reasons;
  for (const auto& c : d->candidates) {
    if (!c.rejected.empty()) reasons.push_back(c.rejected);
  }
  ASSERT_EQ(reasons.size(), 2u);
  EXPECT_NE(reasons[0].find("too long: 40.0 mm"), std::string::npos) << reasons[0];
  EXPECT_NE(reasons[1].find("too small"), std::string::npos) << reasons[1];
}

TEST(FiducialDetection, MatchesRobotFeaturePointsAmongExtraBeads) {
  auto robot = config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml");
  ASSERT_TRUE(robot.ok()) << robot.error().message;
  auto rp = makeRobotPhantom(robot->kinematics, robot->config.registration.scan);
  ASSERT_TRUE(rp.ok()) << rp.error().message;
  // Two extra beads a user might have left on the table.
  auto spec = rp->spec;
  const Points markers = spec.fiducials_lps_mm;
  spec.fiducials_lps_mm.push_back({30.0, -25.0, 10.0});
  spec.fiducials_lps_mm.push_back({-28.0, 20.0, -30.0});
  spec.noise_sigma_hu = 15.0;
  const auto v = phantom(spec);
  const Points model(rp->model_robot_mm.begin(), rp->model_robot_mm.end());
  auto d = findFiducials(v, FiducialSearch{}, model);
  ASSERT_TRUE(d.ok()) << d.error().message;
  ASSERT_TRUE(d->match.has_value()) << d->summary;
  const auto& m = *d->match;
  ASSERT_EQ(m.candidate.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_LT((d->candidates[m.candidate[k]].centroid_lps_mm - markers[k]).norm(), 0.1)
        << "model point " << k;
  }
  EXPECT_LT(m.rms_residual_mm, 0.2);
  // The next-best assignment (through an extra bead) is far worse: a sure choice.
  EXPECT_GT(m.runner_up_rms_mm, 1.0);
  EXPECT_GT(m.runner_up_rms_mm, 5.0 * m.rms_residual_mm);

  // The detected points register the CT to the robot to well under a voxel at the targets.
  Points image;
  for (std::size_t k : m.candidate)
    image.push_back(d->candidates[k].centroid_lps_mm);
  auto reg = registerPoints(image, model, TransformKind::kSimilarity, RegistrationLimits{});
  ASSERT_TRUE(reg.ok()) << reg.error().message;
  for (const Eigen::Vector3d& target_robot :
       {Eigen::Vector3d(0, 15, -170), Eigen::Vector3d(18, -12, -195)}) {
    const Eigen::Vector4d image_h = rp->image_to_robot_true.inverse() * target_robot.homogeneous();
    EXPECT_LT((reg->toRobot(image_h.head<3>()) - target_robot).norm(), 0.15);
  }
}

TEST(FiducialDetection, NoMatchWhenTheModelDoesNotFit) {
  const auto v = phantom(volume::PhantomSpec{});
  const Points model{{0, 0, 0}, {10, 0, 0}, {0, 10, 0}};
  auto d = findFiducials(v, FiducialSearch{}, model);
  ASSERT_TRUE(d.ok());
  EXPECT_FALSE(d->match.has_value());
  EXPECT_NE(d->summary.find("match the model's mutual distances"), std::string::npos) << d->summary;
}

TEST(FiducialDetection, RejectsAThresholdInSoftTissueAndBadSearches) {
  const auto v = phantom(volume::PhantomSpec{});
  FiducialSearch s;
  s.min_hu = -500.0;  // every gelatin voxel
  s.max_bright_voxels = 10000;
  auto d = findFiducials(v, s, {});
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find("min_hu -500"), std::string::npos) << d.error().message;

  s = FiducialSearch{};
  s.min_hu = std::nan("");
  d = findFiducials(v, s, {});
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find("min_hu"), std::string::npos);

  s = FiducialSearch{};
  d = findFiducials(v, s, {{0, 0, 0}, {1, std::nan(""), 0}, {0, 1, 0}});
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find("model point 2"), std::string::npos);
}

TEST(MatchByDistances, FindsThePermutationAndReportsTheRunnerUp) {
  const Points model{{0, 0, 0}, {40, 0, 0}, {0, 25, 0}};
  // Candidates: a shuffled, rotated and shifted copy plus two strays.
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(5, -7, 100);
  const Points candidates{
      {50, 50, 50}, r * model[2] + t, r * model[0] + t, {-40, 3, 9}, r * model[1] + t};
  auto m = matchByDistances(candidates, model, 1.0, 0.5);
  ASSERT_TRUE(m.ok()) << m.error().message;
  EXPECT_EQ(m->candidate, (std::vector<std::size_t>{2, 4, 1}));
  EXPECT_LT(m->rms_residual_mm, 1e-9);
  EXPECT_GT(m->runner_up_rms_mm, 1.0);

  auto few = matchByDistances({candidates[0], candidates[1]}, model, 1.0, 0.5);
  ASSERT_FALSE(few.ok());
  EXPECT_EQ(few.error().reason, "too_few_candidates");

  // An equilateral model fits its own detections in six orders equally well.
  const Points equilateral{{0, 0, 0}, {30, 0, 0}, {15, 15 * std::sqrt(3.0), 0}};
  auto ambiguous = matchByDistances(equilateral, equilateral, 1.0, 0.5);
  ASSERT_FALSE(ambiguous.ok());
  EXPECT_EQ(ambiguous.error().reason, "ambiguous_match");
}

}  // namespace
}  // namespace ignav::registration
