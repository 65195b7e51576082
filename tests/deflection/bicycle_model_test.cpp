// The extended bicycle model against closed forms (the λ = 0 circle), MODEL.md §10's reference
// end states, exact admissibility edges, and fits that recover known tissue parameters.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "ignav/deflection/bicycle_model.hpp"

namespace ignav::deflection {
namespace {

const NeedleModel kPaperNeedle{-1.0 / 400.0, 20.0, -1};  // MODEL.md §10's choices
const Tissue kAgar{0.49, 0.22};                          // seed 000, Table I
const Tissue kPlastisol{0.144, 0.032};

TEST(BicycleModel, PlainModelIsACircleOfRadiusOneOverK) {
  for (double k : {-1.0 / 400.0, 1.0 / 250.0, -1.0 / 90.0}) {
    const NeedleModel n{k, 20.0, -1};
    const auto path = simulate(n, {}, 130.0, 0.5);
    ASSERT_TRUE(path.ok()) << path.error().message;
    ASSERT_EQ(path->size(), 261u);
    for (const auto& p : *path) {
      // γ = k s; z = sin(k s)/k; y = (1 − cos(k s))/k: the circle of radius 1/|k| about (0, 1/k).
      EXPECT_NEAR(p.gamma_rad, k * p.s_mm, 1e-12);
      EXPECT_NEAR(p.z_mm, std::sin(k * p.s_mm) / k, 1e-9);
      EXPECT_NEAR(p.y_mm, (1.0 - std::cos(k * p.s_mm)) / k, 1e-9);
      EXPECT_NEAR(std::hypot(p.z_mm, p.y_mm - 1.0 / k), 1.0 / std::abs(k), 1e-9);
    }
  }
}

TEST(BicycleModel, TableOneTissuesEndWhereModelMdSays) {
  // MODEL.md §10, 130 mm inserted: agar y = −17.11 mm, γ = −0.229; plastisol −20.57; circle
  // −20.94.
  const auto agar = simulate(kPaperNeedle, kAgar, 130.0, 1.0);
  const auto plastisol = simulate(kPaperNeedle, kPlastisol, 130.0, 1.0);
  const auto circle = simulate(kPaperNeedle, {}, 130.0, 1.0);
  ASSERT_TRUE(agar.ok() && plastisol.ok() && circle.ok());
  EXPECT_NEAR(agar->back().y_mm, -17.11, 0.005);
  EXPECT_NEAR(agar->back().gamma_rad, -0.229, 0.0005);
  EXPECT_NEAR(plastisol->back().y_mm, -20.57, 0.005);
  EXPECT_NEAR(circle->back().y_mm, -20.94, 0.005);
  EXPECT_NEAR(circle->back().z_mm, 400.0 * std::sin(130.0 / 400.0), 1e-9);
  // The last sample is at the full length even when the step does not divide it.
  const auto odd = simulate(kPaperNeedle, kAgar, 130.0, 0.7);
  ASSERT_TRUE(odd.ok());
  EXPECT_DOUBLE_EQ(odd->back().s_mm, 130.0);
  EXPECT_NEAR(odd->back().y_mm, agar->back().y_mm, 1e-9);
}

TEST(BicycleModel, OverDepthAgreesWithOverInsertedLength) {
  const auto path = simulate(kPaperNeedle, kAgar, 130.0, 10.0);
  ASSERT_TRUE(path.ok());
  std::vector<double> depths;
  for (const auto& p : *path)
    depths.push_back(p.z_mm);
  const auto y = deflectionAtDepths(kPaperNeedle, kAgar, depths);
  ASSERT_TRUE(y.ok()) << y.error().message;
  for (std::size_t i = 0; i < depths.size(); ++i)
    EXPECT_NEAR((*y)[i], (*path)[i].y_mm, 1e-8) << "depth " << depths[i];
}

TEST(BicycleModel, AdmissibilityIsExactAtItsEdges) {
  EXPECT_TRUE(checkAdmissible(kPaperNeedle, kAgar).admissible);
  EXPECT_TRUE(checkAdmissible(kPaperNeedle, kPlastisol).admissible);
  // (26) λ1 > λ2²/(2π) is sufficient, not necessary: λ1 = 0 with |λ2| < 1 is fine.
  EXPECT_TRUE(checkAdmissible(kPaperNeedle, {0.0, 0.5}).admissible);
  // (24): 1 − α' = 1 − λ2 at γ = 0, so λ2 = 1 is exactly inadmissible; just below is not.
  // (λ1 = 0.1 keeps α(−π/2) = −1.32 rad clear of (23).)
  const auto at_one = checkAdmissible(kPaperNeedle, {0.1, 1.0});
  EXPECT_FALSE(at_one.admissible);
  EXPECT_NE(at_one.reason.find("(24)"), std::string::npos) << at_one.reason;
  EXPECT_TRUE(checkAdmissible(kPaperNeedle, {0.1, 1.0 - 1e-9}).admissible);
  // With λ1 = 0 and λ2 = 1, α(−π/2) = −π/2 exactly: (23) fails first.
  EXPECT_NE(checkAdmissible(kPaperNeedle, {0.0, 1.0}).reason.find("(23)"), std::string::npos);
  // (24) at the other end of [−π/2, 0]: 1 − λ2 + πλ1 = 0.
  EXPECT_FALSE(checkAdmissible(kPaperNeedle, {-0.1, 1.0 - 0.1 * M_PI}).admissible);
  // (23): α(−π/2) = λ1 π²/4 − λ2 π/2 reaches π/2 exactly for λ1 = (π/2 + λ2 π/2)·4/π².
  const double l2 = 0.2;
  const double edge = (M_PI / 2 + l2 * M_PI / 2) * 4.0 / (M_PI * M_PI);
  const auto at_edge = checkAdmissible(kPaperNeedle, {edge * (1 + 1e-12), l2});
  EXPECT_FALSE(at_edge.admissible);
  EXPECT_NE(at_edge.reason.find("(23)"), std::string::npos) << at_edge.reason;
  EXPECT_TRUE(checkAdmissible(kPaperNeedle, {edge * (1 - 1e-9), l2}).admissible);
  // Bending the other way, the range is [0, π/2]: 1 − α' = 1 − πλ1 at γ = π/2 vanishes for
  // λ1 = 1/π, which is harmless for a needle bending towards −y (there it is 1 + πλ1 at −π/2).
  const NeedleModel up{1.0 / 400.0, 20.0, -1};
  EXPECT_FALSE(checkAdmissible(up, {1.0 / M_PI + 1e-9, 0.0}).admissible);
  EXPECT_TRUE(checkAdmissible(up, {1.0 / M_PI - 1e-9, 0.0}).admissible);
  EXPECT_TRUE(checkAdmissible(kPaperNeedle, {1.0 / M_PI + 1e-9, 0.0}).admissible);
  EXPECT_FALSE(simulate(kPaperNeedle, {0.0, 1.0}, 130.0, 1.0).ok());
}

TEST(BicycleModel, BadInputIsRefusedWithItsReason) {
  EXPECT_FALSE(simulate(kPaperNeedle, kAgar, -1.0, 1.0).ok());
  EXPECT_FALSE(simulate(kPaperNeedle, kAgar, 130.0, 0.0).ok());
  EXPECT_FALSE(simulate(kPaperNeedle, kAgar, 130.0, 1e-5).ok());  // 13 million samples
  EXPECT_FALSE(simulate({-1.0 / 400.0, 0.0, -1}, kAgar, 130.0, 1.0).ok());
  EXPECT_FALSE(simulate(kPaperNeedle, {std::nan(""), 0.2}, 130.0, 1.0).ok());
  // A tight needle pushed far turns past 90°: refused, not extrapolated.
  const auto turned = simulate({-1.0 / 20.0, 20.0, -1}, {}, 100.0, 1.0);
  ASSERT_FALSE(turned.ok());
  EXPECT_EQ(turned.error().reason, "turned_back");
  // Pushed on past 90° the integrator stops there instead of crawling towards tan α's pole.
  const auto far = simulate(kPaperNeedle, kAgar, 1000.0, 1000.0);
  ASSERT_FALSE(far.ok());
  EXPECT_EQ(far.error().reason, "turned_back");
  EXPECT_FALSE(deflectionAtDepths(kPaperNeedle, kAgar, {10.0, 5.0}).ok());  // not ascending
}

std::vector<Observation> observe(const Tissue& tissue, double noise_mm, unsigned seed) {
  const auto path = simulate(kPaperNeedle, tissue, 130.0, 2.0).value();
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_mm);
  std::vector<Observation> out;
  for (const auto& p : path) {
    if (p.s_mm == 0.0) continue;
    out.push_back({p.z_mm, p.y_mm + (noise_mm > 0 ? noise(rng) : 0.0)});
  }
  return out;
}

TEST(TissueFit, RecoversTableOneParametersFromNoiseFreePaths) {
  for (const Tissue& truth : {kAgar, kPlastisol}) {
    const auto fit = fitTissue(kPaperNeedle, observe(truth, 0.0, 1));
    ASSERT_TRUE(fit.ok()) << fit.error().message;
    EXPECT_NEAR(fit->tissue.lambda1, truth.lambda1, 1e-6);
    EXPECT_NEAR(fit->tissue.lambda2, truth.lambda2, 1e-6);
    EXPECT_LT(fit->max_error_mm, 1e-6);
  }
}

TEST(TissueFit, NoisyPathsGiveEstimatesWithinTheirStandardErrors) {
  // σ = 0.05 mm (MODEL.md §10: standard errors about ±0.04 and ±0.004, correlation ≈ 0.98).
  int within = 0;
  const int runs = 10;
  for (int seed = 1; seed <= runs; ++seed) {
    const auto fit = fitTissue(kPaperNeedle, observe(kAgar, 0.05, static_cast<unsigned>(seed)));
    ASSERT_TRUE(fit.ok()) << fit.error().message;
    ASSERT_EQ(fit->standard_errors.size(), 2u);
    EXPECT_GT(fit->standard_errors[0], 0.005);
    EXPECT_LT(fit->standard_errors[0], 0.2);
    EXPECT_GT(std::abs(fit->correlation), 0.8);
    within += std::abs(fit->tissue.lambda1 - kAgar.lambda1) < 2 * fit->standard_errors[0] &&
              std::abs(fit->tissue.lambda2 - kAgar.lambda2) < 2 * fit->standard_errors[1];
  }
  EXPECT_GE(within, 7) << "of " << runs;  // ~95 % expected per run
}

TEST(TissueFit, ExtendedModelFitsANonCircularPathBetterThanThePlainOne) {
  // Seed 000's comparison: the path in agar is not a circle, so the plain bicycle model, even
  // with its curvature fitted, misses it by far more than the extended model does.
  const auto fit = fitTissue(kPaperNeedle, observe(kAgar, 0.02, 3));
  ASSERT_TRUE(fit.ok());
  EXPECT_LT(fit->max_error_mm, 0.1);
  EXPECT_GT(fit->max_error_bicycle_mm, 3 * fit->max_error_mm);
  // With the curvature free as well, the fit still recovers the needle's curvature.
  FitOptions o;
  o.fit_curvature = true;
  const auto with_k = fitTissue(kPaperNeedle, observe(kAgar, 0.0, 1), o);
  ASSERT_TRUE(with_k.ok()) << with_k.error().message;
  EXPECT_NEAR(with_k->curvature_per_mm, kPaperNeedle.curvature_per_mm, 1e-7);
  EXPECT_EQ(with_k->standard_errors.size(), 3u);
  // Too few observations for the parameters.
  EXPECT_FALSE(fitTissue(kPaperNeedle, {{10, -1}, {20, -2}}).ok());
}

TEST(TissueFit, MeasurementNoiseAtTheEntryIsDataNotAnError) {
  // Issue 23: `ignav-plan deflection fit` refused a measured path whose first point had a depth
  // of −0.02 mm (the entry point picked a little deep). Noise is data: small negative depths and
  // small steps back are fitted; the model reads a depth above the entry as 0 (no deflection).
  std::vector<Observation> noisy = observe(kAgar, 0.0, 1);
  noisy.insert(noisy.begin(), {-0.02, 0.01});
  noisy.insert(noisy.begin() + 1, {0.5, -0.01});
  std::swap(noisy[5].depth_mm, noisy[6].depth_mm);  // 2 mm apart: a step back beyond 0.5 mm...
  auto refused = fitTissue(kPaperNeedle, noisy);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().reason, "not_a_path");
  EXPECT_NE(refused.error().message.find("observation 7"), std::string::npos)
      << refused.error().message;
  std::swap(noisy[5].depth_mm, noisy[6].depth_mm);
  noisy[6].depth_mm = noisy[5].depth_mm - 0.3;  // ...but 0.3 mm back is noise
  const auto fit = fitTissue(kPaperNeedle, noisy);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  // The perturbed points cost a little accuracy, nothing more.
  EXPECT_NEAR(fit->tissue.lambda1, kAgar.lambda1, 0.05);
  EXPECT_NEAR(fit->tissue.lambda2, kAgar.lambda2, 0.01);
  // Exact data with only a negative entry point: the entry adds y = 0 at depth 0, which is the
  // model's own value there, so the fit is still exact.
  std::vector<Observation> entry = observe(kAgar, 0.0, 1);
  entry.insert(entry.begin(), {-0.02, 0.0});
  const auto exact = fitTissue(kPaperNeedle, entry);
  ASSERT_TRUE(exact.ok()) << exact.error().message;
  EXPECT_NEAR(exact->tissue.lambda1, kAgar.lambda1, 1e-6);
  EXPECT_NEAR(exact->tissue.lambda2, kAgar.lambda2, 1e-6);
  // A path listed from the deepest point back to the entry is one path too.
  std::vector<Observation> backwards(entry.rbegin(), entry.rend());
  const auto reversed = fitTissue(kPaperNeedle, backwards);
  ASSERT_TRUE(reversed.ok()) << reversed.error().message;
  EXPECT_NEAR(reversed->tissue.lambda1, kAgar.lambda1, 1e-6);
}

TEST(TissueFit, WhatCannotBeAPathIsRefusedWithItsReason) {
  const auto path = observe(kAgar, 0.0, 1);
  auto reasonOf = [](const std::vector<Observation>& o) {
    const auto fit = fitTissue(kPaperNeedle, o);
    return fit ? std::string("accepted") : fit.error().reason + ": " + fit.error().message;
  };
  // 5 mm above the entry is not noise.
  std::vector<Observation> above = path;
  above.insert(above.begin(), {-5.0, 0.0});
  EXPECT_EQ(reasonOf(above).rfind("not_a_path: observation 1: depth -5 mm lies above", 0), 0u)
      << reasonOf(above);
  // Two paths in one file: the second starts again at the entry.
  std::vector<Observation> two = path;
  two.insert(two.end(), path.begin(), path.end());
  EXPECT_NE(reasonOf(two).find("not one path"), std::string::npos) << reasonOf(two);
  // All at one depth (within the noise): no path.
  EXPECT_NE(reasonOf({{10, -1}, {10.1, -1.1}, {10.2, -1.2}, {10.3, -1.2}}).find("span 0.3 mm"),
            std::string::npos);
  EXPECT_NE(reasonOf({{10, -1}, {20, std::nan("")}, {30, -2}, {40, -3}}).find("observation 2"),
            std::string::npos);
  // A tolerance is a length.
  FitOptions o;
  o.depth_noise_mm = -1;
  EXPECT_FALSE(fitTissue(kPaperNeedle, path, o).ok());
}

}  // namespace
}  // namespace ignav::deflection
