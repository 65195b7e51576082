// Point registration against independent references: Horn's quaternion method (a different
// algorithm from Umeyama's SVD), exact known transforms, and Monte-Carlo noise statistics for
// the FRE/TRE formulas.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/point_registration.hpp"

namespace ignav::registration {
namespace {

using Points = std::vector<Eigen::Vector3d>;

struct Similarity {
  Eigen::Matrix3d rotation;
  double scale;
  Eigen::Vector3d translation;
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const {
    return scale * rotation * p + translation;
  }
};

Similarity randomSimilarity(std::mt19937_64& rng, double min_scale, double max_scale) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  q.normalize();
  std::uniform_real_distribution<double> scale(min_scale, max_scale);
  std::uniform_real_distribution<double> shift(-300.0, 300.0);
  return {q.toRotationMatrix(), scale(rng), {shift(rng), shift(rng), shift(rng)}};
}

Points randomPoints(std::mt19937_64& rng, std::size_t n, double spread_mm) {
  std::uniform_real_distribution<double> u(-spread_mm, spread_mm);
  Points p;
  for (std::size_t i = 0; i < n; ++i)
    p.emplace_back(u(rng), u(rng), u(rng));
  return p;
}

Points applyAll(const Similarity& t, const Points& points) {
  Points out;
  for (const auto& p : points)
    out.push_back(t.apply(p));
  return out;
}

RegistrationLimits wideLimits() {
  RegistrationLimits l;
  l.min_scale = 1e-3;
  l.max_scale = 1e3;
  l.max_fre_mm = 1e9;
  l.min_separation_mm = 1e-6;
  l.min_spread_from_line_mm = 1e-6;
  return l;
}

// Horn (1987): the rotation is the eigenvector of the largest eigenvalue of a 4×4 matrix built
// from the cross-covariance; the scale Σ q·Rp / Σ|p|² is the least-squares one for that R.
Similarity hornReference(const Points& src, const Points& dst) {
  Eigen::Vector3d cs = Eigen::Vector3d::Zero();
  Eigen::Vector3d cd = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i) {
    cs += src[i];
    cd += dst[i];
  }
  cs /= static_cast<double>(src.size());
  cd /= static_cast<double>(src.size());
  Eigen::Matrix3d s = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i)
    s += (src[i] - cs) * (dst[i] - cd).transpose();
  Eigen::Matrix4d n;
  n << s(0, 0) + s(1, 1) + s(2, 2), s(1, 2) - s(2, 1), s(2, 0) - s(0, 2), s(0, 1) - s(1, 0),
      s(1, 2) - s(2, 1), s(0, 0) - s(1, 1) - s(2, 2), s(0, 1) + s(1, 0), s(2, 0) + s(0, 2),
      s(2, 0) - s(0, 2), s(0, 1) + s(1, 0), -s(0, 0) + s(1, 1) - s(2, 2), s(1, 2) + s(2, 1),
      s(0, 1) - s(1, 0), s(2, 0) + s(0, 2), s(1, 2) + s(2, 1), -s(0, 0) - s(1, 1) + s(2, 2);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(n);
  const Eigen::Vector4d v = eig.eigenvectors().col(3);
  const Eigen::Matrix3d r = Eigen::Quaterniond(v(0), v(1), v(2), v(3)).toRotationMatrix();
  double num = 0.0;
  double den = 0.0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    num += (dst[i] - cd).dot(r * (src[i] - cs));
    den += (src[i] - cs).squaredNorm();
  }
  const double scale = num / den;
  return {r, scale, cd - scale * r * cs};
}

TEST(PointRegistration, RecoversRandomSimilaritiesExactly) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    const auto truth = randomSimilarity(rng, 0.5, 2.0);
    const auto image = randomPoints(rng, 3 + trial % 6, 80.0);
    auto r =
        registerPoints(image, applyAll(truth, image), TransformKind::kSimilarity, wideLimits());
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_NEAR(r->scale, truth.scale, 1e-12);
    EXPECT_LT((r->rotation - truth.rotation).norm(), 1e-12);
    EXPECT_LT((r->translation_mm - truth.translation).norm(), 1e-9);
    EXPECT_LT(r->fre_mm, 1e-9);
    EXPECT_NEAR(r->rotation.determinant(), 1.0, 1e-12);
  }
}

TEST(PointRegistration, NoisyFitAgreesWithHornsQuaternionMethod) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 0.4);
  for (int trial = 0; trial < 100; ++trial) {
    const auto truth = randomSimilarity(rng, 0.8, 1.2);
    const auto image = randomPoints(rng, 3 + trial % 5, 60.0);
    auto robot = applyAll(truth, image);
    for (auto& p : robot)
      p += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    const auto ref = hornReference(image, robot);
    auto r = registerPoints(image, robot, TransformKind::kSimilarity, wideLimits());
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_NEAR(r->scale, ref.scale, 1e-10);
    EXPECT_LT((r->rotation - ref.rotation).norm(), 1e-9);
    EXPECT_LT((r->translation_mm - ref.translation).norm(), 1e-8);
    // FRE is the RMS of the per-point residuals, each |T(image_i) - robot_i|.
    double sum_sq = 0.0;
    for (std::size_t i = 0; i < image.size(); ++i) {
      const double e = (ref.apply(image[i]) - robot[i]).norm();
      EXPECT_NEAR(r->residuals_mm[i], e, 1e-8);
      sum_sq += e * e;
    }
    EXPECT_NEAR(r->fre_mm, std::sqrt(sum_sq / static_cast<double>(image.size())), 1e-8);
  }
}

TEST(PointRegistration, QuarterTurnAboutZClosedForm) {
  // robot = 2 · Rz(90°) · image + (10, 20, 30): (1,0,0) -> (10, 22, 30) etc.
  const Points image{{1, 0, 0}, {0, 3, 0}, {0, 0, 5}, {2, 2, 2}};
  const Points robot{{10, 22, 30}, {4, 20, 30}, {10, 20, 40}, {6, 24, 34}};
  auto r = registerPoints(image, robot, TransformKind::kSimilarity, wideLimits());
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_NEAR(r->scale, 2.0, 1e-12);
  EXPECT_LT((r->toRobot({0, 0, 0}) - Eigen::Vector3d(10, 20, 30)).norm(), 1e-12);
  EXPECT_LT((r->toRobot({1, 1, 0}) - Eigen::Vector3d(8, 22, 30)).norm(), 1e-12);
  EXPECT_LT((r->toImage({8, 22, 30}) - Eigen::Vector3d(1, 1, 0)).norm(), 1e-12);
}

TEST(PointRegistration, RigidKeepsUnitScale) {
  const Points image{{0, 0, 0}, {40, 0, 0}, {0, 30, 0}, {0, 0, 20}};
  Points robot;
  for (const auto& p : image)
    robot.push_back(1.05 * p + Eigen::Vector3d(1, 2, 3));
  auto rigid = registerPoints(image, robot, TransformKind::kRigid, wideLimits());
  auto similarity = registerPoints(image, robot, TransformKind::kSimilarity, wideLimits());
  ASSERT_TRUE(rigid.ok() && similarity.ok());
  EXPECT_DOUBLE_EQ(rigid->scale, 1.0);
  EXPECT_GT(rigid->fre_mm, 0.5);
  EXPECT_NEAR(similarity->scale, 1.05, 1e-12);
  EXPECT_LT(similarity->fre_mm, 1e-9);
}

TEST(PointRegistration, MirroredNonCoplanarSetLeavesResidual) {
  // MODEL.md §9: a proper rotation cannot match a mirror image of 4 non-coplanar points.
  const Points image{{0, 0, 0}, {30, 0, 0}, {0, 20, 0}, {0, 0, 10}};
  Points robot;
  for (const auto& p : image)
    robot.emplace_back(-p.x(), p.y(), p.z());
  auto r = registerPoints(image, robot, TransformKind::kRigid, wideLimits());
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR(r->rotation.determinant(), 1.0, 1e-12);
  EXPECT_GT(r->fre_mm, 1.0);
}

// --- rejections -------------------------------------------------------------------------------

const Points kImage{{0, 0, 0}, {40, 0, 0}, {0, 30, 0}};

Error rejection(const Points& image, const Points& robot,
                const RegistrationLimits& limits = RegistrationLimits{}) {
  auto r = registerPoints(image, robot, TransformKind::kSimilarity, limits);
  EXPECT_FALSE(r.ok());
  return r.ok() ? Error{} : r.error();
}

TEST(PointRegistrationRejects, FewerThanThreePairs) {
  const auto e = rejection({{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}});
  EXPECT_EQ(e.reason, "too_few_pairs");
  EXPECT_EQ(e.code, ErrorCode::kInvalidArgument);
  EXPECT_NE(e.message.find("2 point pairs"), std::string::npos) << e.message;
}

TEST(PointRegistrationRejects, MismatchedCounts) {
  const auto e = rejection(kImage, {{0, 0, 0}, {1, 0, 0}});
  EXPECT_EQ(e.reason, "count_mismatch");
  EXPECT_NE(e.message.find("3 image points but 2 robot points"), std::string::npos) << e.message;
}

TEST(PointRegistrationRejects, NonFiniteValuesNamingThePoint) {
  for (double bad : {std::nan(""), HUGE_VAL, -HUGE_VAL}) {
    Points robot = kImage;
    robot[1].y() = bad;
    const auto e = rejection(kImage, robot);
    EXPECT_EQ(e.reason, "non_finite");
    EXPECT_NE(e.message.find("robot point 2"), std::string::npos) << e.message;
  }
}

TEST(PointRegistrationRejects, CoordinatesBeyondAnyScanner) {
  Points image = kImage;
  image[0].x() = 1e308;  // finite, but its square is not
  const auto e = rejection(image, kImage);
  EXPECT_EQ(e.reason, "out_of_range");
  EXPECT_NE(e.message.find("image point 1"), std::string::npos) << e.message;
}

TEST(PointRegistrationRejects, CoincidentPointsInEitherFrame) {
  const Points twice{{0, 0, 0}, {40, 0, 0}, {40.3, 0.2, 0}};
  auto e = rejection(twice, kImage);
  EXPECT_EQ(e.reason, "coincident");
  EXPECT_NE(e.message.find("image points 2 and 3 are 0.36 mm apart"), std::string::npos)
      << e.message;
  e = rejection(kImage, twice);
  EXPECT_EQ(e.reason, "coincident");
  EXPECT_NE(e.message.find("robot points 2 and 3"), std::string::npos) << e.message;
}

TEST(PointRegistrationRejects, CollinearAndNearlyCollinearSets) {
  const Points line{{0, 0, 0}, {20, 0, 0}, {50, 0, 0}};
  auto e = rejection(line, kImage);
  EXPECT_EQ(e.reason, "collinear");
  EXPECT_EQ(e.code, ErrorCode::kDegenerate);
  // 0.5 mm off the line over 50 mm: numerically fine, clinically a coin toss about the axis.
  const Points nearly{{0, 0, 0}, {20, 0.75, 0}, {50, 0, 0}};
  e = rejection(kImage, nearly);
  EXPECT_EQ(e.reason, "collinear");
  EXPECT_NE(e.message.find("robot points lie within 0.35 mm"), std::string::npos) << e.message;
  // The paper's warning case: base and cannula tip on the axis, stylet retracted onto it.
  const Points on_axis{{0, 0, -95}, {0, 0, -135}, {0, 0, -160}};
  EXPECT_EQ(rejection(kImage, on_axis).reason, "collinear");
}

TEST(PointRegistrationRejects, ImplausibleScale) {
  Points robot;
  for (const auto& p : kImage)
    robot.push_back(2.0 * p);
  const auto e = rejection(kImage, robot);
  EXPECT_EQ(e.reason, "scale_out_of_range");
  EXPECT_NE(e.message.find("2.0000"), std::string::npos) << e.message;
}

TEST(PointRegistrationRejects, ResidualAboveLimit) {
  const Points image{{0, 0, 0}, {40, 0, 0}, {0, 30, 0}, {0, 0, 25}};
  Points robot = image;
  robot[3].z() += 8.0;
  const auto e = rejection(image, robot);
  EXPECT_EQ(e.reason, "fre_too_large");
  EXPECT_NE(e.message.find("worst: pair 4"), std::string::npos) << e.message;
}

// --- noise statistics against Monte-Carlo ----------------------------------------------------

struct MonteCarlo {
  double fre_rms = 0.0;
  std::vector<double> tre_rms;
};

// Isotropic Gaussian FLE on the image points (σ per axis = FLE/√3); the robot points exact.
MonteCarlo simulate(const Points& image, const Points& targets, double fle_mm, TransformKind kind,
                    int trials) {
  std::mt19937_64 rng(20261122);
  std::normal_distribution<double> noise(0.0, fle_mm / std::sqrt(3.0));
  // Truth: identity; any other similarity only rescales the figures.
  MonteCarlo mc;
  mc.tre_rms.assign(targets.size(), 0.0);
  double fre_sq = 0.0;
  for (int t = 0; t < trials; ++t) {
    Points noisy = image;
    for (auto& p : noisy)
      p += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    auto r = registerPoints(noisy, image, kind, wideLimits());
    EXPECT_TRUE(r.ok());
    fre_sq += r->fre_mm * r->fre_mm;
    for (std::size_t i = 0; i < targets.size(); ++i) {
      mc.tre_rms[i] += (r->toRobot(targets[i]) - targets[i]).squaredNorm();
    }
  }
  mc.fre_rms = std::sqrt(fre_sq / trials);
  for (auto& v : mc.tre_rms)
    v = std::sqrt(v / trials);
  return mc;
}

void expectFormulasMatchMonteCarlo(const Points& fiducials, const Points& targets,
                                   TransformKind kind) {
  const double fle = 0.5;
  const auto mc = simulate(fiducials, targets, fle, kind, 6000);
  EXPECT_NEAR(mc.fre_rms / expectedFre_mm(fiducials.size(), fle, kind), 1.0, 0.03)
      << toString(kind) << " N=" << fiducials.size();
  const auto config = describeFiducials(fiducials);
  for (std::size_t i = 0; i < targets.size(); ++i) {
    const double predicted = expectedTre_mm(config, targets[i], fle, kind);
    EXPECT_NEAR(mc.tre_rms[i] / predicted, 1.0, 0.04)
        << toString(kind) << " N=" << fiducials.size() << " target " << i << ": MC "
        << mc.tre_rms[i] << " vs " << predicted;
  }
}

TEST(RegistrationErrors, FitzpatrickWestMatchesMonteCarloOnThePapersFeaturePoints) {
  auto robot = config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml");
  ASSERT_TRUE(robot.ok()) << robot.error().message;
  const Points fiducials(robot->feature_points_mm.begin(), robot->feature_points_mm.end());
  // Targets across the feasible volume, near and far from the fiducials.
  const Points targets{{0, 10, -150}, {15, -10, -175}, {-20, 15, -200}, {0, 0, -95}};
  expectFormulasMatchMonteCarlo(fiducials, targets, TransformKind::kRigid);
  expectFormulasMatchMonteCarlo(fiducials, targets, TransformKind::kSimilarity);
}

TEST(RegistrationErrors, FitzpatrickWestMatchesMonteCarloForSixFiducials) {
  std::mt19937_64 rng(3);
  const auto fiducials = randomPoints(rng, 6, 40.0);
  const Points targets{{0, 0, 0}, {60, 0, 0}, {-30, 50, 20}};
  expectFormulasMatchMonteCarlo(fiducials, targets, TransformKind::kRigid);
  expectFormulasMatchMonteCarlo(fiducials, targets, TransformKind::kSimilarity);
}

TEST(RegistrationErrors, TreAtTheCentroidIsFleOverRootN) {
  // Fitzpatrick–West at r = centroid: every d_k = 0, so TRE = FLE/√N for a rigid fit.
  const Points fiducials{{10, 0, 0}, {-10, 0, 0}, {0, 15, 0}, {0, -15, 0}};
  const auto config = describeFiducials(fiducials);
  EXPECT_NEAR(expectedTre_mm(config, config.centroid_mm, 0.8, TransformKind::kRigid), 0.4, 1e-12);
  EXPECT_NEAR(
      estimatedFle_mm(4, expectedFre_mm(4, 0.8, TransformKind::kRigid), TransformKind::kRigid), 0.8,
      1e-12);
}

// A matrix from elsewhere (3D Slicer over OpenIGTLink): accepted when it is a proper similarity,
// refused with the reason otherwise.
TEST(RegistrationFromMatrix, ASimilarityIsTakenAsIs) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).matrix();
  m.topLeftCorner<3, 3>() = 1.05 * r;
  m.topRightCorner<3, 1>() << 10, -20, 30;
  auto reg = registrationFromMatrix(m, RegistrationLimits{});
  ASSERT_TRUE(reg.ok()) << reg.error().message;
  EXPECT_NEAR(reg->scale, 1.05, 1e-12);
  EXPECT_LT((reg->rotation - r).cwiseAbs().maxCoeff(), 1e-12);
  const Eigen::Vector3d p(3, 4, -5);
  EXPECT_LT((reg->toRobot(p) - (1.05 * r * p + Eigen::Vector3d(10, -20, 30))).norm(), 1e-12);
  EXPECT_LT((reg->toImage(reg->toRobot(p)) - p).norm(), 1e-12);
  EXPECT_EQ(reg->kind, TransformKind::kSimilarity);
  m.topLeftCorner<3, 3>() = r;
  EXPECT_EQ(registrationFromMatrix(m, RegistrationLimits{})->kind, TransformKind::kRigid);
}

TEST(RegistrationFromMatrix, WhatIsNotARegistrationIsRefusedWithItsReason) {
  const auto reason = [](const Eigen::Matrix4d& m) {
    auto reg = registrationFromMatrix(m, RegistrationLimits{});
    return reg.ok() ? std::string("accepted") : reg.error().reason;
  };
  const Eigen::Matrix4d id = Eigen::Matrix4d::Identity();
  Eigen::Matrix4d m = id;
  m(0, 1) = 0.05;
  EXPECT_EQ(reason(m), "not_similarity");
  m = id;
  m(2, 2) = -1;  // RAS and LPS mixed up would mirror two axes; one is a mirror
  EXPECT_EQ(reason(m), "mirror");
  m = id;
  m(1, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(reason(m), "non_finite");
  m = id;
  m(3, 0) = 0.1;
  EXPECT_EQ(reason(m), "not_affine");
  m = 1.5 * id;
  m(3, 3) = 1;
  EXPECT_EQ(reason(m), "scale_out_of_range");
  m = id;
  m(0, 3) = 1e7;
  EXPECT_EQ(reason(m), "out_of_range");
  EXPECT_EQ(reason(Eigen::Matrix4d::Zero()), "not_affine");
}

}  // namespace
}  // namespace ignav::registration
