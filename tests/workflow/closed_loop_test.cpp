// The closed loop in the reducer (issue 23), without DDS: the robot moves to its targets on the
// simulated controller (workflow/bench.hpp), a confirmation CT's outcome is fed as the analysis
// thread would (markers and seeds placed where a known truth puts them), and the errors, the
// refusals, the click fallback, the tissue fit and the compensated aim are checked against that
// truth and against independent computations (forward kinematics, the deflection model).
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <numeric>

#include "ignav/compensation/compensation.hpp"
#include "ignav/config/tissue_profiles.hpp"
#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/reducer.hpp"
#include "workflow/bench.hpp"

namespace ignav::workflow {
namespace {

using rig::Bench;
using test::paperRobot;

constexpr double kDeg = M_PI / 180.0;
// Six targets at six depths and six planes (the fit needs them apart).
const std::vector<kinematics::Joints> kJoints = {{30 * kDeg, 10, 25},  {-60 * kDeg, 20, 30},
                                                 {150 * kDeg, 5, 35},  {90 * kDeg, 15, 20},
                                                 {200 * kDeg, 25, 28}, {-120 * kDeg, 30, 15}};

constexpr auto* profile = &rig::tissueProfile;

// A session that moved to `count` targets and retracted: done.
Bench insertedBench(std::size_t count, std::optional<config::TissueProfile> tissue = {}) {
  Bench b(0, std::move(tissue));
  for (std::size_t i = 0; i < count; ++i)
    b.addRobotTarget(kJoints[i]);
  EXPECT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  while (b.s.pending) {
    EXPECT_TRUE(b.send(b.approvePending()).accepted);
    b.runMotion();
  }
  EXPECT_EQ(b.s.phase, Phase::kDone);
  return b;
}

// What the analysis thread reports for a scan whose markers and seeds lie where `scan_to_session`
// (a rigid motion of the whole scan, image LPS -> image LPS) puts them: the markers of the
// planning CT, and a seed at each robot-frame point.
Input scanned(const Session& s, std::uint64_t job, const std::vector<Eigen::Vector3d>& seeds_robot,
              const Eigen::Isometry3d& scan_to_session = Eigen::Isometry3d::Identity()) {
  Input in;
  in.kind = InputKind::kConfirmationMeasured;
  in.job = job;
  in.path = "/scans/confirmation";
  in.summary = "test scan";
  const Eigen::Isometry3d session_to_scan = scan_to_session.inverse();
  for (const auto& m : s.registration->image_mm)
    in.points.push_back(session_to_scan * m);
  std::uint32_t id = 0;
  for (const auto& p : seeds_robot) {
    FoundSeed seed;
    seed.id = ++id;
    seed.lps_mm = session_to_scan * s.registration->toImage(p);
    seed.length_mm = 3.0;
    seed.width_mm = 0.8;
    in.seeds.push_back(seed);
  }
  return in;
}

// A command whose path is a name (fit_tissue, use_tissue), with a fresh request id.
// Where each reached target's seed lands in a tissue the server does not know.
std::vector<Eigen::Vector3d> landedIn(const Bench& b, const compensation::DeflectionModel& tissue) {
  std::vector<Eigen::Vector3d> landed;
  for (const auto& t : b.s.targets) {
    landed.push_back(
        compensation::predictLanding(paperRobot()->kinematics, tissue, t.reached_joints)
            .value()
            .tip_mm);
  }
  return landed;
}

// Replay's CT: the phantom's grid, as the bench loaded it.
Expected<LoadedCt> phantomGridAgain(const std::string&) {
  LoadedCt ct;
  ct.volume = ignav::test::phantomCtGrid(*paperRobot());
  ct.source = "phantom:";
  return ct;
}

Input named(Bench& b, InputKind kind, const std::string& name) {
  Input in = b.command(kind);
  in.path = name;
  return in;
}

std::uint64_t startMeasuring(Bench& b) {
  auto load = b.command(InputKind::kLoadConfirmation);
  load.path = "/scans/confirmation";
  const Step step = b.feed(load);
  EXPECT_TRUE(step.effects.replies.at(0).accepted) << step.effects.replies.at(0).message;
  EXPECT_EQ(step.effects.start_jobs, std::vector<JobKind>{JobKind::kConfirmationMeasurement});
  return b.s.confirmation.measuring;
}

std::vector<Eigen::Vector3d> plannedPlus(const Session& s, const std::vector<Eigen::Vector3d>& d) {
  std::vector<Eigen::Vector3d> out;
  for (std::size_t i = 0; i < d.size(); ++i)
    out.push_back(s.targets[i].robot_mm + d[i]);
  return out;
}

const std::vector<Eigen::Vector3d> kOffsets = {
    {1.2, -0.8, -1.5}, {-2.0, 0.6, 0.9}, {0.4, 2.1, -0.7}, {-1.1, -1.3, 0.4}};

TEST(ClosedLoop, ErrorsAreTheSeedsDisplacementsInTheRobotFrame) {
  Bench b = insertedBench(4);
  const auto job = startMeasuring(b);
  ASSERT_NE(job, 0u);
  EXPECT_EQ(b.s.phase, Phase::kDone);  // measuring changes no phase
  b.feed(scanned(b.s, job, plannedPlus(b.s, kOffsets)));
  const Confirmation& c = b.s.confirmation;
  ASSERT_EQ(c.status, "measured") << c.message;
  EXPECT_EQ(c.measuring, 0u);
  ASSERT_TRUE(c.registration.has_value());
  EXPECT_TRUE(c.registration->reused);
  ASSERT_EQ(c.targets.size(), 4u);
  double sum = 0.0;
  for (std::size_t i = 0; i < 4; ++i) {
    const auto& e = c.targets[i].error;
    EXPECT_EQ(e.target_id, b.s.targets[i].id);
    EXPECT_LT((e.error_robot_mm - kOffsets[i]).norm(), 1e-9);
    EXPECT_NEAR(e.depth_mm, -kOffsets[i].z(), 1e-9);  // + deeper, deeper is -z
    EXPECT_NEAR(e.lateral_mm, kOffsets[i].head<2>().norm(), 1e-9);
    EXPECT_EQ(c.targets[i].matched, "detected");
    sum += kOffsets[i].norm();
  }
  ASSERT_TRUE(c.summary.has_value());
  EXPECT_NEAR(c.summary->error.mean, sum / 4.0, 1e-9);
  EXPECT_TRUE(c.missing_targets.empty());
  EXPECT_TRUE(c.extra_seeds.empty());
}

TEST(ClosedLoop, AScanOfAMovedPatientIsRegisteredAnewAndMeasuresTheSame) {
  Bench b = insertedBench(4);
  const auto job = startMeasuring(b);
  // The whole scan 6 mm and 2° away from the planning CT: markers and seeds alike.
  Eigen::Isometry3d moved = Eigen::Isometry3d::Identity();
  moved.rotate(Eigen::AngleAxisd(2 * kDeg, Eigen::Vector3d::UnitZ()));
  moved.pretranslate(Eigen::Vector3d(4.0, -3.0, 3.0));
  b.feed(scanned(b.s, job, plannedPlus(b.s, kOffsets), moved));
  const Confirmation& c = b.s.confirmation;
  ASSERT_EQ(c.status, "measured") << c.message;
  EXPECT_FALSE(c.registration->reused);
  EXPECT_GT(c.registration->marker_shift_mm, 4.0);
  for (std::size_t i = 0; i < 4; ++i)
    EXPECT_LT((c.targets[i].error.error_robot_mm - kOffsets[i]).norm(), 1e-6) << i;
}

TEST(ClosedLoop, BadScansAreRefusedWithTheReasonAndTheMeasurementBeforeStays) {
  Bench b = insertedBench(4);
  b.feed(scanned(b.s, startMeasuring(b), plannedPlus(b.s, kOffsets)));
  ASSERT_EQ(b.s.confirmation.status, "measured");
  const auto before = b.s.confirmation.targets;
  auto expectRefused = [&](const Input& in, const std::string& why) {
    b.feed(in);
    const Confirmation& c = b.s.confirmation;
    EXPECT_EQ(c.status, "measured");
    EXPECT_EQ(c.measuring, 0u);
    ASSERT_EQ(c.targets.size(), before.size());
    EXPECT_EQ(c.targets[0].error.error_robot_mm, before[0].error.error_robot_mm);
    EXPECT_NE(c.message.find(why), std::string::npos) << c.message;
    EXPECT_NE(c.message.find("stays"), std::string::npos) << c.message;
  };
  // Another patient or frame: the markers 50 mm off.
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.pretranslate(Eigen::Vector3d(50.0, 0.0, 0.0));
  expectRefused(scanned(b.s, startMeasuring(b), plannedPlus(b.s, kOffsets), far), "far");
  // No seeds in the scan.
  expectRefused(scanned(b.s, startMeasuring(b), {}), "no_seeds");
  // The analysis thread could not find the markers (or load the scan).
  Input failed;
  failed.kind = InputKind::kConfirmationFailed;
  failed.job = startMeasuring(b);
  failed.path = "/scans/other";
  failed.error = "markers_missing: the robot's markers were not found";
  expectRefused(failed, "markers_missing");
  // An outcome nobody waits for changes nothing at all.
  const auto revision = b.s.revision;
  const Step stale = b.feed(scanned(b.s, 999, plannedPlus(b.s, kOffsets)));
  EXPECT_EQ(b.s.revision, revision);
  EXPECT_EQ(stale.effects.replies.at(0).error_code, "stale_detection");
}

TEST(ClosedLoop, AScanGivenWithItsMatrixIsRegisteredByItNotByItsMarkers) {
  Bench b = insertedBench(4);
  // The scan 6 mm and 2° away from the planning CT; its markers unusable (here 50 mm off: merged
  // with a needle left in, or out of the field of view).
  Eigen::Isometry3d moved = Eigen::Isometry3d::Identity();
  moved.rotate(Eigen::AngleAxisd(2 * kDeg, Eigen::Vector3d::UnitZ()));
  moved.pretranslate(Eigen::Vector3d(4.0, -3.0, 3.0));
  const Eigen::Matrix4d given = b.s.registration->imageToRobot() * moved.matrix();
  auto load = [&](const Eigen::Matrix4d& m) {
    auto in = b.command(InputKind::kLoadConfirmation);
    in.path = "/scans/confirmation";
    in.matrix = m;
    return b.send(in);
  };
  // A transform that is no proper similarity, or not finite: refused before any work.
  const auto mirrored = load(given * Eigen::Vector4d(-1.0, 1.0, 1.0, 1.0).asDiagonal());
  EXPECT_EQ(mirrored.error_code, "mirror") << mirrored.message;
  EXPECT_NE(mirrored.message.find("matrix"), std::string::npos) << mirrored.message;
  Eigen::Matrix4d nan = given;
  nan(0, 3) = std::nan("");
  EXPECT_FALSE(load(nan).accepted);
  EXPECT_EQ(b.s.confirmation.measuring, 0u);
  EXPECT_EQ(b.s.confirmation.status, "none");

  const auto r = load(given);
  ASSERT_TRUE(r.accepted) << r.message;
  Input scan = scanned(b.s, b.s.confirmation.measuring, plannedPlus(b.s, kOffsets), moved);
  for (auto& m : scan.points)
    m += Eigen::Vector3d(50.0, 0.0, 0.0);
  b.feed(scan);
  const Confirmation& c = b.s.confirmation;
  ASSERT_EQ(c.status, "measured") << c.message;
  EXPECT_TRUE(c.registration->by_matrix);
  EXPECT_TRUE(std::isnan(c.registration->marker_shift_mm));
  for (std::size_t i = 0; i < 4; ++i)
    EXPECT_LT((c.targets[i].error.error_robot_mm - kOffsets[i]).norm(), 1e-6) << i;
  // The next scan without a matrix is judged by its markers again.
  startMeasuring(b);
  EXPECT_FALSE(b.s.confirmation.measuring_matrix.has_value());
}

TEST(ClosedLoop, MoreSeedsThanTargetsNeedAPersonWhoRejectsTheExtra) {
  Bench b = insertedBench(3);
  auto seeds = plannedPlus(b.s, {kOffsets[0], kOffsets[1], kOffsets[2]});
  seeds.push_back(b.s.targets[0].robot_mm + Eigen::Vector3d(0.0, 0.0, 8.0));  // a stray seed
  b.feed(scanned(b.s, startMeasuring(b), seeds));
  ASSERT_EQ(b.s.confirmation.status, "unmatched") << b.s.confirmation.message;
  EXPECT_NE(b.s.confirmation.message.find("more_seeds_than_targets"), std::string::npos)
      << b.s.confirmation.message;
  EXPECT_TRUE(b.s.confirmation.targets.empty());
  // An unknown seed id is refused; rejecting the stray one (#4) gives the measurement.
  EXPECT_EQ(b.send(b.command(InputKind::kRejectSeed, {}, {99})).error_code, "unknown_seed");
  const auto r = b.send(b.command(InputKind::kRejectSeed, {}, {4}));
  ASSERT_TRUE(r.accepted) << r.message;
  ASSERT_EQ(b.s.confirmation.status, "measured") << b.s.confirmation.message;
  ASSERT_EQ(b.s.confirmation.targets.size(), 3u);
  EXPECT_LT((b.s.confirmation.targets[0].error.error_robot_mm - kOffsets[0]).norm(), 1e-9);
}

TEST(ClosedLoop, AScanWhoseMatchNeedsAPersonKeepsTheRowsMeasuredBefore) {
  // Issue 40: a second scan whose seeds cannot be matched alone (a stray seed: more seeds than
  // targets) cleared the first scan's rows (8 → 0). They stay, named as the first scan's, until
  // a person settles the second; then the second's rows replace them. Replay derives the same.
  Bench b = insertedBench(4);
  b.feed(scanned(b.s, startMeasuring(b), plannedPlus(b.s, kOffsets)));
  ASSERT_EQ(b.s.confirmation.status, "measured");
  const auto first = b.s.confirmation.targets;
  ASSERT_EQ(first.size(), 4u);
  auto seeds = plannedPlus(b.s, {kOffsets[1], kOffsets[2], kOffsets[3], kOffsets[0]});
  seeds.push_back(b.s.targets[0].robot_mm + Eigen::Vector3d(0.0, 0.0, 8.0));  // a stray seed
  Input second = scanned(b.s, startMeasuring(b), seeds);
  second.path = "/scans/second";
  b.feed(second);
  const Confirmation& c = b.s.confirmation;
  ASSERT_EQ(c.status, "unmatched") << c.message;
  EXPECT_EQ(c.source, "/scans/second");
  EXPECT_EQ(c.rows_source, "/scans/confirmation");
  ASSERT_EQ(c.targets.size(), first.size());
  for (std::size_t i = 0; i < first.size(); ++i)
    EXPECT_EQ(c.targets[i].error.error_robot_mm, first[i].error.error_robot_mm) << i;
  EXPECT_NE(c.message.find("the errors measured on /scans/confirmation stay"), std::string::npos)
      << c.message;
  // Settled: the second scan's own rows.
  ASSERT_TRUE(b.send(b.command(InputKind::kRejectSeed, {}, {5})).accepted);
  ASSERT_EQ(c.status, "measured") << c.message;
  EXPECT_EQ(c.rows_source, "/scans/second");
  EXPECT_LT((c.targets[0].error.error_robot_mm - kOffsets[1]).norm(), 1e-9);
}

TEST(ClosedLoop, APlacedSeedWinsOverTheDetectionAndAMissingOneIsReported) {
  Bench b = insertedBench(3);
  // Target 3's seed was not found; target 2's was found 1 mm from where it truly is.
  auto seeds = plannedPlus(b.s, {kOffsets[0], kOffsets[1]});
  b.feed(scanned(b.s, startMeasuring(b), seeds));
  const Confirmation& c = b.s.confirmation;
  ASSERT_EQ(c.status, "measured") << c.message;
  ASSERT_EQ(c.missing_targets, std::vector<std::uint32_t>{b.s.targets[2].id});
  EXPECT_NE(c.text.find("no seed for T" + std::to_string(b.s.targets[2].id)), std::string::npos);
  // The person clicks the missing seed on the confirmation CT.
  const Eigen::Vector3d clicked = b.s.registration->toImage(b.s.targets[2].robot_mm + kOffsets[2]);
  ASSERT_TRUE(b.send(b.command(InputKind::kPlaceSeed, {clicked}, {b.s.targets[2].id})).accepted);
  ASSERT_EQ(c.targets.size(), 3u);
  EXPECT_TRUE(c.missing_targets.empty());
  EXPECT_EQ(c.targets[2].matched, "placed");
  EXPECT_LT((c.targets[2].error.error_robot_mm - kOffsets[2]).norm(), 1e-9);
  // Accepting a detected match keeps it; a target that was never reached has no seed.
  ASSERT_TRUE(b.send(b.command(InputKind::kAcceptSeed, {}, {b.s.targets[0].id})).accepted);
  EXPECT_EQ(c.targets[0].matched, "accepted");
  EXPECT_EQ(b.send(b.command(InputKind::kPlaceSeed, {clicked}, {77})).error_code, "unknown_target");
}

TEST(ClosedLoop, SeedCommandsBeforeAnyMeasurementAndLoadsBeforeAnyMotionAreRefused) {
  Bench b;
  b.addRobotTarget(kJoints[0]);
  auto load = b.command(InputKind::kLoadConfirmation);
  load.path = "/scans/confirmation";
  EXPECT_EQ(b.send(load).error_code, "nothing_reached");
  EXPECT_EQ(b.send(b.command(InputKind::kRejectSeed, {}, {1})).error_code, "no_confirmation");
  EXPECT_EQ(b.send(named(b, InputKind::kFitTissue, "gel")).error_code, "no_confirmation");
  EXPECT_EQ(b.send(named(b, InputKind::kFitTissue, "a name with spaces")).error_code, "bad_name");
}

// The loop closed in the model: the seeds land where a tissue the session was not told deflects
// the needle; the fit recovers it; aiming with the fitted profile lands on the targets.
TEST(ClosedLoop, TheFittedTissueIsTheHiddenOneAndAimingWithItLandsOnTheTargets) {
  const auto told = profile("agar", 0.49, 0.22);
  Bench b = insertedBench(6, told);
  compensation::DeflectionModel hidden;
  hidden.needle = told.needle;
  hidden.tissue = {0.30, 0.15};
  b.feed(scanned(b.s, startMeasuring(b), landedIn(b, hidden)));
  ASSERT_EQ(b.s.confirmation.status, "measured") << b.s.confirmation.message;
  // What the told tissue had predicted is on every row.
  for (const auto& m : b.s.confirmation.targets)
    EXPECT_TRUE(std::isfinite(m.predicted_error_mm));
  const auto fitted = b.send(named(b, InputKind::kFitTissue, "hidden_gel"));
  ASSERT_TRUE(fitted.accepted) << fitted.message;
  ASSERT_EQ(b.s.fitted_tissues.size(), 1u);
  const FittedTissue f = b.s.fitted_tissues[0];  // a copy: the list grows below
  EXPECT_NEAR(f.profile.tissue.lambda1, 0.30, 1e-3) << fitted.message;
  EXPECT_NEAR(f.profile.tissue.lambda2, 0.15, 1e-3) << fitted.message;
  EXPECT_NE(f.yaml.find("hidden_gel:"), std::string::npos) << f.yaml;

  // Aim with it: only with the plan open, only a known name.
  EXPECT_EQ(b.send(named(b, InputKind::kUseTissue, "hidden_gel")).error_code, "wrong_phase");
  ASSERT_TRUE(b.send(b.command(InputKind::kUnlockPlan)).accepted);
  ASSERT_TRUE(b.send(b.command(InputKind::kClearTargets)).accepted);
  // The measurement outlives the plan's targets: the fit still has its joints.
  const auto again_fitted = b.send(named(b, InputKind::kFitTissue, "hidden_gel_again"));
  ASSERT_TRUE(again_fitted.accepted) << again_fitted.message;
  EXPECT_NEAR(b.s.fitted_tissues.at(1).profile.tissue.lambda1, 0.30, 1e-3);
  const auto unknown = b.send(named(b, InputKind::kUseTissue, "granite"));
  EXPECT_EQ(unknown.error_code, "unknown_tissue");
  EXPECT_NE(unknown.message.find("agar, hidden_gel, hidden_gel_again"), std::string::npos)
      << unknown.message;
  ASSERT_TRUE(b.send(named(b, InputKind::kUseTissue, "hidden_gel")).accepted);
  std::vector<double> nominal_off, compensated_off;
  for (std::size_t i = 0; i < 4; ++i) {
    const auto& t = b.target(b.addRobotTarget(kJoints[i]));
    ASSERT_TRUE(t.compensated.has_value()) << t.message;
    // Independently: where the hidden tissue takes each set of joints.
    const auto at = [&](const kinematics::Joints& j) {
      return compensation::predictLanding(paperRobot()->kinematics, hidden, j).value().tip_mm;
    };
    nominal_off.push_back((at(t.solution.joints) - t.robot_mm).norm());
    compensated_off.push_back((at(t.compensated->joints) - t.robot_mm).norm());
    EXPECT_LT(compensated_off.back(), 0.01) << t.message;  // the fit's own small error
    EXPECT_EQ(t.steps, paperRobot()->transmission.toSteps(t.compensated->joints).steps);
  }
  const double mean_nominal = std::accumulate(nominal_off.begin(), nominal_off.end(), 0.0) /
                              static_cast<double>(nominal_off.size());
  const double mean_compensated =
      std::accumulate(compensated_off.begin(), compensated_off.end(), 0.0) /
      static_cast<double>(compensated_off.size());
  EXPECT_GT(mean_nominal, 5.0 * mean_compensated);
  // The approval request shows the nominal and the compensated joints and the landing point.
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  ASSERT_TRUE(b.s.pending.has_value());
  EXPECT_NE(b.s.pending->summary.find("compensated for tissue 'hidden_gel'"), std::string::npos)
      << b.s.pending->summary;
  EXPECT_NE(b.s.pending->summary.find("predicted landing"), std::string::npos);

  // The journal holds all of it: replayed, the same session.
  Session replayed = newSession("bench", paperRobot(), "robot.yaml");
  auto again = replayJournal(replayed, b.journal, phantomGridAgain, "journal");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(again->revision, b.s.revision);
  ASSERT_EQ(again->fitted_tissues.size(), 2u);
  EXPECT_EQ(again->fitted_tissues[0].profile.tissue.lambda1, f.profile.tissue.lambda1);
  ASSERT_TRUE(again->pending.has_value());
  EXPECT_EQ(again->pending->digest, b.s.pending->digest);
}

// A fit judged wrong is forgotten: no longer offered to use_tissue; the aim drops it with the plan
// open, and a locked plan aiming with it is refused, not changed under its approval.
TEST(ClosedLoop, ADiscardedFitIsForgottenAndTheAimDropsItOnlyWithThePlanOpen) {
  const auto told = profile("agar", 0.49, 0.22);
  Bench b = insertedBench(6, told);
  const compensation::DeflectionModel hidden{told.needle, {0.30, 0.15}};
  b.feed(scanned(b.s, startMeasuring(b), landedIn(b, hidden)));
  ASSERT_TRUE(b.send(named(b, InputKind::kFitTissue, "gel_a")).accepted);
  ASSERT_TRUE(b.send(named(b, InputKind::kFitTissue, "gel_b")).accepted);
  ASSERT_TRUE(b.send(b.command(InputKind::kUnlockPlan)).accepted);
  ASSERT_TRUE(b.send(b.command(InputKind::kClearTargets)).accepted);
  ASSERT_TRUE(b.send(named(b, InputKind::kUseTissue, "gel_a")).accepted);
  const std::uint32_t id = b.addRobotTarget(kJoints[0]);
  ASSERT_TRUE(b.target(id).compensated.has_value());
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);

  const auto unknown =
      b.send(named(b, InputKind::kDiscardTissue, "agar"));  // configured, not fitted
  EXPECT_EQ(unknown.error_code, "unknown_tissue");
  EXPECT_NE(unknown.message.find("fitted: gel_a, gel_b"), std::string::npos) << unknown.message;
  const auto locked = b.send(named(b, InputKind::kDiscardTissue, "gel_a"));
  EXPECT_EQ(locked.error_code, "wrong_phase");
  EXPECT_NE(locked.message.find("is not open (plan_locked)"), std::string::npos) << locked.message;
  EXPECT_EQ(b.s.fitted_tissues.size(), 2u);
  EXPECT_TRUE(b.target(id).compensated.has_value());
  // Another fit goes while the plan stays locked (its approval request dies with the change).
  ASSERT_TRUE(b.send(named(b, InputKind::kDiscardTissue, "gel_b")).accepted);
  ASSERT_EQ(b.s.fitted_tissues.size(), 1u);
  EXPECT_EQ(b.s.fitted_tissues[0].profile.name, "gel_a");
  EXPECT_EQ(b.send(named(b, InputKind::kUseTissue, "gel_b")).error_code, "wrong_phase");

  ASSERT_TRUE(b.send(b.command(InputKind::kUnlockPlan)).accepted);
  EXPECT_EQ(b.send(named(b, InputKind::kUseTissue, "gel_b")).error_code, "unknown_tissue");
  const auto discarded = b.send(named(b, InputKind::kDiscardTissue, "gel_a"));
  ASSERT_TRUE(discarded.accepted) << discarded.message;
  EXPECT_NE(discarded.message.find("aimed as planned"), std::string::npos) << discarded.message;
  EXPECT_TRUE(b.s.fitted_tissues.empty());
  EXPECT_FALSE(b.s.aim_tissue.has_value());
  const auto& t = b.target(id);
  EXPECT_FALSE(t.compensated.has_value());
  EXPECT_EQ(t.steps, paperRobot()->transmission.toSteps(t.solution.joints).steps);

  Session replayed = newSession("bench", paperRobot(), "robot.yaml");
  auto again = replayJournal(replayed, b.journal, phantomGridAgain, "journal");
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(again->revision, b.s.revision);
  EXPECT_TRUE(again->fitted_tissues.empty());
  EXPECT_FALSE(again->aim_tissue.has_value());
}

}  // namespace
}  // namespace ignav::workflow
