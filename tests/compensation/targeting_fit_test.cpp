// The tissue fitted from targeting errors: a hidden tissue deflects every insertion (the
// independent reference of reference.hpp plays the phantom), the fit must find it again.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>

#include "fixtures.hpp"
#include "reference.hpp"

namespace ignav::compensation {
namespace {

using test::kConfigs;
using test::paperRobot;
using test::profile;

// A session's worth of targets (the paper's 21), aimed without compensation, landing where the
// hidden tissue puts them, measured with isotropic noise of `noise_mm` per axis.
std::vector<TargetingRecord> session(const kinematics::Kinematics& kin,
                                     const DeflectionModel& hidden, double noise_mm, unsigned seed,
                                     int count = 21) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> t(0, 2 * M_PI), c(2, 38), s(3, 38);
  std::normal_distribution<double> noise(0.0, noise_mm);
  std::vector<TargetingRecord> out;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d planned = kin.forward({t(rng), c(rng), s(rng)}).tip_mm;
    const auto joints = kin.inverse(planned)->joints;
    Eigen::Vector3d actual = reference::landing(kin, hidden, joints);
    if (noise_mm > 0) actual += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    out.push_back({"t" + std::to_string(i + 1), planned, joints, actual, {}});
  }
  return out;
}

TEST(TargetingFit, RecoversAHiddenTissueFromExactErrors) {
  const auto& kin = paperRobot();
  for (const char* name : {"agar", "plastisol"}) {
    const DeflectionModel hidden = profile(name);
    // The server knows the needle, not the tissue: it starts from the default guess.
    DeflectionModel known = hidden;
    known.tissue = {};
    const auto fit = fitTissueFromTargeting(kin, known, session(kin, hidden, 0.0, 1));
    ASSERT_TRUE(fit.ok()) << fit.error().message;
    std::cout << name << ": λ1 " << fit->tissue.lambda1 << ", λ2 " << fit->tissue.lambda2 << " in "
              << fit->iterations << " iterations; RMS " << fit->rms_mm << " mm (plain bicycle "
              << fit->rms_bicycle_mm << ", none " << fit->rms_no_deflection_mm << ")\n";
    EXPECT_NEAR(fit->tissue.lambda1, hidden.tissue.lambda1, 1e-5);
    EXPECT_NEAR(fit->tissue.lambda2, hidden.tissue.lambda2, 1e-6);
    EXPECT_LT(fit->max_error_mm, 1e-8);
    EXPECT_GT(fit->rms_no_deflection_mm, 0.5);  // the errors were there to explain
  }
}

TEST(TargetingFit, NoisyErrorsGiveEstimatesWithinTheirStandardErrors) {
  // 0.1–0.2 mm of localisation noise per axis over the paper's 21 targets.
  const auto& kin = paperRobot();
  const DeflectionModel agar = profile("agar");
  DeflectionModel known = agar;
  known.tissue = {};
  int within = 0, runs = 0, at_limit = 0;
  for (double noise : {0.1, 0.15, 0.2}) {
    for (unsigned seed = 1; seed <= 5; ++seed, ++runs) {
      const auto fit = fitTissueFromTargeting(kin, known, session(kin, agar, noise, seed));
      ASSERT_TRUE(fit.ok()) << fit.error().message;
      const auto& se = fit->standard_errors;
      // λ1 acts through γ², and γ stays below 0.1 rad within 40 mm of insertion: it is weakly
      // determined, and some runs end on the admissibility limit (reported, SE one-sided).
      if (!fit->limit.empty()) {
        ++at_limit;
        EXPECT_NE(fit->limit.find("λ1 = "), std::string::npos) << fit->limit;
      }
      ASSERT_EQ(se.size(), 2u);
      if (seed == 1) {
        std::cout << "σ " << noise << " mm: λ1 " << fit->tissue.lambda1 << " ± " << se[0] << ", λ2 "
                  << fit->tissue.lambda2 << " ± " << se[1] << ", corr " << fit->correlation
                  << ", RMS " << fit->rms_mm << " mm (plain bicycle " << fit->rms_bicycle_mm
                  << ")\n";
      }
      // Sane: grows with the noise, nowhere near zero or the parameters' own scale times ten.
      EXPECT_GT(se[0], 0.01 * noise);
      EXPECT_LT(se[0], 20 * noise);
      EXPECT_GT(se[1], 0.001 * noise);
      EXPECT_LT(se[1], 2 * noise);
      // The residual RMS estimates the noise (3-D: √3 σ).
      EXPECT_NEAR(fit->rms_mm, std::sqrt(3.0) * noise, 0.5 * noise);
      within += std::abs(fit->tissue.lambda1 - agar.tissue.lambda1) < 2 * se[0] &&
                std::abs(fit->tissue.lambda2 - agar.tissue.lambda2) < 2 * se[1];
    }
  }
  std::cout << within << " of " << runs << " within 2 SE; " << at_limit << " on the limit\n";
  EXPECT_GE(within, runs - 3) << "of " << runs;  // ~90 % expected for both at 2 SE
}

TEST(TargetingFit, TheLoopCompensatedWithTheFittedTissueLandsFiveTimesCloser) {
  // The workflow in the model: plan → move (hidden agar) → measure (0.15 mm noise) →
  // fit → a second, compensated pass on the same targets with the fitted tissue.
  const auto& kin = paperRobot();
  const DeflectionModel agar = profile("agar");
  DeflectionModel known = agar;
  known.tissue = {};
  const auto first = session(kin, agar, 0.15, 21);
  const auto fit = fitTissueFromTargeting(kin, known, first);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  DeflectionModel fitted = known;
  fitted.tissue = fit->tissue;
  double before = 0.0, after = 0.0;
  int n = 0;
  for (const auto& r : first) {
    const auto c = compensate(kin, fitted, r.planned_mm);
    if (!c) continue;  // out of reach once compensated
    before += (reference::landing(kin, agar, r.joints) - r.planned_mm).norm();
    after += (reference::landing(kin, agar, c->compensated) - r.planned_mm).norm();
    ++n;
  }
  ASSERT_GE(n, 12);
  std::cout << n << " targets: mean model error " << before / n << " mm uncompensated, "
            << after / n << " mm compensated with the fitted tissue\n";
  EXPECT_LT(5 * after, before);
}

TEST(TargetingFit, CurvatureCanBeFittedToo) {
  const auto& kin = paperRobot();
  DeflectionModel hidden = profile("plastisol");
  hidden.needle.curvature_per_mm = -1.0 / 300.0;
  DeflectionModel known = hidden;
  known.tissue = {};
  known.needle.curvature_per_mm = -1.0 / 400.0;  // the configured needle, off by a third
  TargetingFitOptions options;
  options.fit_curvature = true;
  const auto fit = fitTissueFromTargeting(kin, known, session(kin, hidden, 0.0, 4, 30), options);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  EXPECT_NEAR(fit->curvature_per_mm, -1.0 / 300.0, 1e-8);
  EXPECT_NEAR(fit->tissue.lambda1, hidden.tissue.lambda1, 1e-4);
  EXPECT_NEAR(fit->tissue.lambda2, hidden.tissue.lambda2, 1e-5);
  EXPECT_EQ(fit->standard_errors.size(), 3u);
}

TEST(TargetingFit, ExtendedModelExplainsAgarBetterThanThePlainOne) {
  // Seed 000's comparison on targeting errors: λ = 0 with its curvature fitted cannot follow
  // agar's non-circular drift as well, though at ≤ 40 mm insertions the gap is modest.
  const auto& kin = paperRobot();
  const DeflectionModel agar = profile("agar");
  DeflectionModel known = agar;
  known.tissue = {};
  const auto fit = fitTissueFromTargeting(kin, known, session(kin, agar, 0.0, 2));
  ASSERT_TRUE(fit.ok());
  EXPECT_GT(fit->rms_bicycle_mm, 100 * fit->rms_mm);
  EXPECT_LT(fit->rms_bicycle_mm, fit->rms_no_deflection_mm);
  // Early on agar turns faster than the needle's own k (γ' = k / (1 − λ2) at γ = 0): over these
  // short insertions the best circle is tighter than 1/400 mm.
  EXPECT_LT(fit->bicycle_curvature_per_mm, -1.0 / 400.0);
  EXPECT_TRUE(fit->limit.empty());
}

// RMS (3-D, over the landings) of the records against a tissue, by the independent reference.
double rmsAgainst(const kinematics::Kinematics& kin, const DeflectionModel& model,
                  const std::vector<TargetingRecord>& records) {
  double sum = 0.0;
  for (const auto& r : records)
    sum += (reference::landing(kin, model, r.joints) - r.actual_mm).squaredNorm();
  return std::sqrt(sum / static_cast<double>(records.size()));
}

TEST(TargetingFit, AStrongSlipIsFoundWhereTheGuessAloneStalls) {
  // Issue 40: hidden tissues with λ2 ≥ 0.5 stalled from the default guess at RMS 0.341 mm, worse
  // than the plain bicycle model. The fit must end no worse than the hidden tissue itself (a
  // point it could have reached: the global minimum lies at or below it) and no worse than the
  // plain model it extends (λ = 0), both judged by the independent reference integrator.
  const auto& kin = paperRobot();
  for (const deflection::Tissue hidden_tissue : {deflection::Tissue{0.2, 0.5}, {0.1, 0.6}}) {
    DeflectionModel hidden = profile("agar");
    hidden.tissue = hidden_tissue;
    DeflectionModel known = hidden;
    known.tissue = {};
    const auto records = session(kin, hidden, 0.03, 7);
    const auto fit = fitTissueFromTargeting(kin, known, records);
    ASSERT_TRUE(fit.ok()) << fit.error().message;
    DeflectionModel fitted = known;
    fitted.tissue = fit->tissue;
    const double at_fit = rmsAgainst(kin, fitted, records);
    const double at_truth = rmsAgainst(kin, hidden, records);
    const double plain = rmsAgainst(kin, known, records);
    std::cout << "hidden (" << hidden_tissue.lambda1 << ", " << hidden_tissue.lambda2 << "): λ1 "
              << fit->tissue.lambda1 << " ± " << fit->standard_errors[0] << ", λ2 "
              << fit->tissue.lambda2 << " ± " << fit->standard_errors[1] << ", RMS " << at_fit
              << " mm (hidden tissue " << at_truth << ", λ = 0 " << plain << ", plain bicycle "
              << fit->rms_bicycle_mm << "); won from " << fit->start << " of " << fit->starts
              << "\n";
    EXPECT_NEAR(fit->rms_mm, at_fit, 1e-4);  // the module's figure is the reference's
    EXPECT_LE(at_fit, at_truth + 1e-4);
    EXPECT_LT(at_fit, plain);
    EXPECT_LT(at_fit, fit->rms_bicycle_mm);
    EXPECT_NEAR(fit->tissue.lambda2, hidden_tissue.lambda2, 3 * fit->standard_errors[1]);
  }
}

TEST(TargetingFit, ErrorsTheModelCannotExplainAreRefusedWithTheFigures) {
  // Issue 40: on random errors a fit was accepted (λ1 0.679 ± 20.6, RMS worse than no deflection)
  // and aiming would have used it. Random errors (0.5 mm SD per axis) about the nominal landings,
  // no tissue at all: refused, with the RMS figures, for any of several draws.
  const auto& kin = paperRobot();
  const DeflectionModel known = profile("none");
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, 0.5);
    auto records = session(kin, known, 0.0, 40 + seed);
    for (auto& r : records) {
      r.actual_mm =
          kin.forward(r.joints).tip_mm + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    }
    const auto fit = fitTissueFromTargeting(kin, known, records);
    ASSERT_FALSE(fit.ok()) << "seed " << seed << ": λ1 " << fit->tissue.lambda1 << " ± "
                           << fit->standard_errors[0] << ", RMS " << fit->rms_mm << " (none "
                           << fit->rms_no_deflection_mm << ")";
    const auto& why = fit.error();
    EXPECT_TRUE(why.reason == "explains_nothing" || why.reason == "underdetermined") << why.reason;
    EXPECT_NE(why.message.find("with no deflection"), std::string::npos) << why.message;
    EXPECT_NE(why.message.find("not offered for aiming"), std::string::npos) << why.message;
  }
}

TEST(TargetingFit, UnusableRecordsAreRefusedWithTheReason) {
  const auto& kin = paperRobot();
  const DeflectionModel agar = profile("agar");
  auto records = session(kin, agar, 0.0, 3);
  // No insertion at all: nothing about the tissue in the errors.
  auto shallow = records;
  for (auto& r : shallow) {
    r.joints.z_c_mm = 0.0;
    r.actual_mm = kin.forward(r.joints).tip_mm;
  }
  auto f = fitTissueFromTargeting(kin, agar, shallow);
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.error().reason, "underdetermined");
  // One target: two in-plane residuals for two parameters leave no residual to judge them by.
  f = fitTissueFromTargeting(kin, agar, {records[0]});
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.error().reason, "underdetermined");
  EXPECT_NE(f.error().message.find("1 targets for 2 parameters"), std::string::npos);
  // Every target at one depth, the stylet carried without turning: each error is the same
  // cannula drift (lateral, shortfall), two numbers for λ1, λ2 and k.
  DeflectionModel translated = agar;
  translated.carry = StyletCarry::kTranslated;
  auto one_depth = records;
  for (auto& r : one_depth) {
    r.joints.z_c_mm = 20.0;
    r.actual_mm = reference::landing(kin, translated, r.joints);
  }
  TargetingFitOptions with_k;
  with_k.fit_curvature = true;
  f = fitTissueFromTargeting(kin, translated, one_depth, with_k);
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.error().reason, "underdetermined") << f.error().message;
  EXPECT_NE(f.error().message.find("span z_c 20.0–20.0 mm"), std::string::npos)
      << f.error().message;
  // A fit cut short does not converge, and says so.
  TargetingFitOptions hurried;
  hurried.max_evaluations = 2;
  f = fitTissueFromTargeting(kin, agar, records, hurried);
  ASSERT_FALSE(f.ok());
  EXPECT_EQ(f.error().reason, "not_converged") << f.error().message;
  // Errors no tissue can make (every seed 30 mm too shallow): whatever the fit ends on explains
  // next to nothing, and it is refused with the figures.
  auto wild = records;
  for (auto& r : wild)
    r.actual_mm += Eigen::Vector3d(0, 0, 30);
  f = fitTissueFromTargeting(kin, agar, wild);
  ASSERT_FALSE(f.ok());
  EXPECT_TRUE(f.error().reason == "explains_nothing" || f.error().reason == "underdetermined")
      << f.error().message;
  EXPECT_NE(f.error().message.find("with no deflection"), std::string::npos) << f.error().message;
  // Bad values name the target.
  auto bad = records;
  bad[4].actual_mm.x() = std::nan("");
  f = fitTissueFromTargeting(kin, agar, bad);
  ASSERT_FALSE(f.ok());
  EXPECT_NE(f.error().message.find("target 't5'"), std::string::npos);
  bad = records;
  bad[2].joints.z_c_mm = 45;
  EXPECT_NE(fitTissueFromTargeting(kin, agar, bad).error().message.find("z_c_mm = 45"),
            std::string::npos);
}

TEST(TargetingFit, ResultIsANamedProfileThatTheConfigLoads) {
  const auto& kin = paperRobot();
  const DeflectionModel agar = profile("agar");
  DeflectionModel known = agar;
  known.tissue = {};
  const auto fit = fitTissueFromTargeting(kin, known, session(kin, agar, 0.1, 8));
  ASSERT_TRUE(fit.ok());
  const auto entry = tissueProfileYaml("session_8", *fit, "21 targets, \"H\" + helix", false);
  ASSERT_TRUE(entry.ok()) << entry.error().message;
  TargetingFit with_k = *fit;
  with_k.curvature_per_mm = -0.003;
  const auto entry_k = tissueProfileYaml("session_8k", with_k, "fitted with k", true);
  ASSERT_TRUE(entry_k.ok());
  const auto dir = std::filesystem::temp_directory_path() / "ignav_compensation_profile";
  std::filesystem::create_directories(dir);
  std::ifstream bundled(kConfigs + "tissues.yaml");
  std::ofstream(dir / "tissues.yaml") << bundled.rdbuf() << *entry << *entry_k;
  const auto profiles = config::loadTissueProfiles((dir / "tissues.yaml").string());
  ASSERT_TRUE(profiles.ok()) << profiles.error().message;
  const auto p = config::tissueProfile(*profiles, "session_8");
  ASSERT_TRUE(p.ok());
  EXPECT_EQ(p->tissue.lambda1, fit->tissue.lambda1);  // exact: shortest round-trip digits
  EXPECT_EQ(p->tissue.lambda2, fit->tissue.lambda2);
  EXPECT_EQ(p->needle.curvature_per_mm, agar.needle.curvature_per_mm);
  EXPECT_NE(p->source.find("'H' + helix"), std::string::npos) << p->source;
  EXPECT_EQ(config::tissueProfile(*profiles, "session_8k")->needle.curvature_per_mm, -0.003);
  EXPECT_EQ(config::tissueProfile(*profiles, "agar")->needle.curvature_per_mm, -0.0025);
  EXPECT_FALSE(tissueProfileYaml("my tissue: x", *fit, "", false).ok());
  std::filesystem::remove_all(dir);
}

// Points every 2 mm along the whole needle as the hidden tissue bends it (cannula from 10 mm above
// the tissue, then the stylet): what a CT that still shows the needle gives.
std::vector<Eigen::Vector3d> visiblePath(const kinematics::Kinematics& kin,
                                         const DeflectionModel& hidden,
                                         const kinematics::Joints& joints, double noise_mm,
                                         std::mt19937& rng) {
  // Sampled finely (exact points of the curve), then every 2 mm.
  auto path = predictPath(kin, hidden, joints, 0.05, 10.0);
  EXPECT_TRUE(path.ok());
  std::vector<Eigen::Vector3d> all = path->cannula_mm, out;
  all.insert(all.end(), path->stylet_mm.begin(), path->stylet_mm.end());
  for (std::size_t i = 0; i < all.size(); i += 40)
    out.push_back(all[i]);
  std::normal_distribution<double> noise(0.0, noise_mm);
  if (noise_mm > 0) {
    for (auto& q : out)
      q += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  }
  return out;
}

TEST(TargetingFit, OneVisibleNeedlePathDeterminesTheTissue) {
  // One target alone cannot separate λ1 from λ2 (two in-plane errors, two parameters, and λ1
  // acts weakly); the same target with its needle still in the CT can: the path's shape along the
  // whole insertion is the bicycle model's own observable (seed 000 fits paths, not endpoints).
  const auto& kin = paperRobot();
  const DeflectionModel hidden = profile("agar");
  DeflectionModel known = hidden;
  known.tissue = {};
  const kinematics::Joints joints{0.4, 38.0, 25.0};
  const Eigen::Vector3d planned = kin.forward(joints).tip_mm;
  const Eigen::Vector3d actual = reference::landing(kin, hidden, joints);
  TargetingRecord alone{"t1", planned, joints, actual, {}};
  const auto without = fitTissueFromTargeting(kin, known, {alone});
  EXPECT_FALSE(without.ok());
  std::mt19937 rng(3);
  TargetingRecord seen = alone;
  seen.path_mm = visiblePath(kin, hidden, joints, 0.0, rng);
  const auto exact = fitTissueFromTargeting(kin, known, {seen});
  ASSERT_TRUE(exact.ok()) << exact.error().message;
  // λ1 acts weakly: the predicted path's chords (35 nm of sag) already move it in the third digit.
  EXPECT_NEAR(exact->tissue.lambda1, hidden.tissue.lambda1, 2e-3);
  EXPECT_NEAR(exact->tissue.lambda2, hidden.tissue.lambda2, 1e-4);
  EXPECT_LT(exact->max_error_mm, 1e-4);
  // With 0.1 mm of centreline noise per axis, and four targets at several depths.
  int within = 0, runs = 0;
  for (unsigned seed = 1; seed <= 6; ++seed, ++runs) {
    std::mt19937 noisy(seed);
    std::vector<TargetingRecord> records;
    for (const kinematics::Joints& j :
         {kinematics::Joints{0.4, 38.0, 25.0}, kinematics::Joints{2.0, 20.0, 35.0},
          kinematics::Joints{3.5, 30.0, 12.0}, kinematics::Joints{5.1, 12.0, 30.0}}) {
      TargetingRecord r{"t", kin.forward(j).tip_mm, j, reference::landing(kin, hidden, j), {}};
      r.path_mm = visiblePath(kin, hidden, j, 0.1, noisy);
      records.push_back(r);
    }
    const auto fit = fitTissueFromTargeting(kin, known, records);
    ASSERT_TRUE(fit.ok()) << fit.error().message;
    const auto& se = fit->standard_errors;
    if (seed == 1) {
      std::cout << "paths, σ 0.1 mm: λ1 " << fit->tissue.lambda1 << " ± " << se[0] << ", λ2 "
                << fit->tissue.lambda2 << " ± " << se[1] << "\n";
    }
    within += std::abs(fit->tissue.lambda1 - hidden.tissue.lambda1) < 2 * se[0] &&
              std::abs(fit->tissue.lambda2 - hidden.tissue.lambda2) < 2 * se[1];
  }
  // Both within 2 SE: ~90 % of runs for an unbiased fit; 4 of 6 or more unless biased (a run of
  // bad luck below that has probability ~2 %; the seeds are fixed).
  EXPECT_GE(within, runs - 2);
}

TEST(TargetingFit, ANonFinitePathPointIsRefusedNamingTheTarget) {
  const auto& kin = paperRobot();
  const kinematics::Joints j{0.4, 38.0, 25.0};
  TargetingRecord r{"t7", kin.forward(j).tip_mm, j, kin.forward(j).tip_mm, {}};
  r.path_mm = {Eigen::Vector3d(0, 0, std::nan(""))};
  const auto fit = fitTissueFromTargeting(kin, profile("agar"), {r, r, r});
  ASSERT_FALSE(fit.ok());
  EXPECT_NE(fit.error().message.find("'t7'"), std::string::npos) << fit.error().message;
  EXPECT_NE(fit.error().message.find("path"), std::string::npos) << fit.error().message;
}

}  // namespace
}  // namespace ignav::compensation
