// Approval-gated motion without DDS: the reducer's controller commands run on a
// SimulatedController exactly as the server runs them (workflow/bench.hpp: halts first, moves
// after the journal), and the safety invariants are checked where they matter: at the controller
// boundary (SimulatedController::movesStarted).
#include <gtest/gtest.h>

#include <type_traits>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include <functional>
#include <iostream>
#include <random>
#include <set>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/workflow/effect_order.hpp"
#include "ignav/workflow/reducer.hpp"
#include "support/phantom_ct.hpp"
#include "workflow/bench.hpp"

namespace ignav::workflow {
namespace {

using actuation::ControllerState;
using actuation::ControllerStatus;
using actuation::Steps;

using rig::Bench;
using rig::policy;
using test::paperRobot;

const kinematics::Joints kJointsA{30.0 * M_PI / 180.0, 10.0, 25.0};
const kinematics::Joints kJointsB{-60.0 * M_PI / 180.0, 20.0, 30.0};
const kinematics::Joints kJointsC{150.0 * M_PI / 180.0, 5.0, 35.0};

TEST(Sha256, KnownAnswerVectors) {
  // FIPS 180-2, appendix B.1 and the empty message.
  EXPECT_EQ(sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(Approval, LockOrdersTheTargetsAndRequestsApprovalOfTheFirstMotion) {
  Bench b;
  const auto a = b.addRobotTarget(kJointsA);
  const auto c = b.addRobotTarget(kJointsC);
  const auto bb = b.addRobotTarget(kJointsB);
  const auto reply = b.send(b.command(InputKind::kLockPlan));
  ASSERT_TRUE(reply.accepted) << reply.message;
  EXPECT_EQ(b.s.phase, Phase::kPlanLocked);
  // IK gives θc in [0°, 360°): 30°, 150° and 300° (-60°). From θc = 0 only the rising sweep
  // stays within 360° of rotation (300° in all); every other order turns 450° or more.
  std::vector<std::uint32_t> order;
  for (const auto& t : b.s.targets)
    order.push_back(t.id);
  EXPECT_EQ(order, (std::vector<std::uint32_t>{a, c, bb})) << reply.message;
  EXPECT_NE(reply.message.find("cannula rotation 300.0°"), std::string::npos) << reply.message;
  ASSERT_TRUE(b.s.pending.has_value());
  const auto& p = *b.s.pending;
  EXPECT_EQ(p.target_id, order.front());
  EXPECT_EQ(p.from, Steps{});
  EXPECT_EQ(p.digest, requestDigest(scopeOf(b.s), p));
  EXPECT_EQ(p.digest.size(), 64u);
  EXPECT_NE(p.summary.find("T" + std::to_string(p.target_id)), std::string::npos) << p.summary;
  EXPECT_NE(reply.message.find("cannula rotation"), std::string::npos) << reply.message;
  // The moves add up to the target's steps through the transmission, an independent route.
  Steps sum;
  for (const auto& m : p.moves)
    for (std::size_t k = 0; k < 3; ++k)
      sum.motor[k] += m.steps.motor[k];
  EXPECT_EQ(sum, paperRobot()->transmission.toSteps(b.target(p.target_id).solution.joints).steps);
  // Any change to one increment changes the digest.
  MotionRequest changed = p;
  changed.moves.back().steps.motor[2] += 1;
  EXPECT_NE(requestDigest(scopeOf(b.s), changed), p.digest);
  EXPECT_EQ(b.sim().movesStarted(), 0u);
}

// Issue 38: two robots whose session folders have one name and whose plans are alike must not
// share a digest, or one robot's approval moves the other.
TEST(Approval, ADigestIsBoundToItsRobotAndItsSession) {
  Bench cell_c(0, std::nullopt, "cell-c", "1b4e28ba-2fa1-41d2-883f-0016d3cca427");
  Bench cell_d(0, std::nullopt, "cell-d", "7c9e6679-7425-40de-944b-e07fc1f90ae7");
  Bench cell_c_again(0, std::nullopt, "cell-c", "f47ac10b-58cc-4372-a567-0e02b2c3d479");
  for (Bench* b : {&cell_c, &cell_d, &cell_c_again}) {
    b->addRobotTarget(kJointsA);
    ASSERT_TRUE(b->send(b->command(InputKind::kLockPlan)).accepted);
    ASSERT_TRUE(b->s.pending.has_value());
  }
  // The same folder name, plan id, start and steps: only the robot and the session differ.
  ASSERT_EQ(cell_c.s.session_id, cell_d.s.session_id);
  ASSERT_EQ(cell_c.s.pending->plan_id, cell_d.s.pending->plan_id);
  ASSERT_EQ(cell_c.s.pending->from, cell_d.s.pending->from);
  ASSERT_EQ(cell_c.s.pending->moves.size(), cell_d.s.pending->moves.size());
  for (std::size_t k = 0; k < cell_c.s.pending->moves.size(); ++k)
    ASSERT_EQ(cell_c.s.pending->moves[k].steps, cell_d.s.pending->moves[k].steps);
  const std::string c_digest = cell_c.s.pending->digest;
  EXPECT_NE(c_digest, cell_d.s.pending->digest);
  EXPECT_NE(c_digest, cell_c_again.s.pending->digest);  // one robot, another session

  for (Bench* other : {&cell_d, &cell_c_again}) {
    const auto r = other->send(other->approve(other->s.pending->plan_id, c_digest));
    EXPECT_FALSE(r.accepted);
    EXPECT_EQ(r.error_code, "wrong_digest") << r.message;
    EXPECT_EQ(other->s.phase, Phase::kPlanLocked);
    EXPECT_EQ(other->sim().movesStarted(), 0u);
  }
  // Its own digest still moves it.
  ASSERT_TRUE(cell_d.send(cell_d.approvePending()).accepted);
  EXPECT_EQ(cell_d.s.phase, Phase::kMoving);
}

TEST(Approval, ApprovedMotionArrivesAtEveryTargetThenRetracts) {
  Bench b;
  b.addRobotTarget(kJointsA);
  b.addRobotTarget(kJointsB);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  std::size_t moves = 0;
  for (int visit = 0; visit < 2; ++visit) {
    const auto target_id = b.s.pending.value().target_id;
    moves += b.s.pending->moves.size();
    const auto r = b.send(b.approvePending());
    ASSERT_TRUE(r.accepted) << r.message;
    EXPECT_EQ(b.s.phase, Phase::kMoving);
    b.runMotion();
    ASSERT_EQ(b.s.phase, Phase::kAtTarget) << b.s.fault;
    const auto& t = b.target(target_id);
    EXPECT_TRUE(t.reached);
    EXPECT_EQ(t.status(), "reached");
    // Where the motors are is what the transmission makes of the IK joints.
    const auto expected = paperRobot()->transmission.toSteps(t.solution.joints).steps;
    EXPECT_EQ(b.reading().position, expected);
    EXPECT_EQ(b.s.position, expected);
    // ... and the tip they give is the clicked target, to the steps' resolution (θc's half
    // step of 0.28° is 0.1 mm at 20 mm from the axis).
    const auto at =
        paperRobot()->kinematics.forward(paperRobot()->transmission.toJoints(b.reading().position));
    EXPECT_LT((at.tip_mm - t.robot_mm).norm(), 0.15);
  }
  ASSERT_TRUE(b.s.pending.has_value());
  EXPECT_EQ(b.s.pending->target_id, 0u);  // the final retraction
  moves += b.s.pending->moves.size();
  ASSERT_TRUE(b.send(b.approvePending()).accepted);
  b.runMotion();
  EXPECT_EQ(b.s.phase, Phase::kDone);
  // The report lists every approved motion with its approver and outcome.
  const std::string report = procedureReport(b.s);
  ASSERT_EQ(b.s.motions.size(), 3u);
  EXPECT_NE(report.find(fmt::format("| 1 | T{} | surgeon |", b.s.motions[0].target_id)),
            std::string::npos)
      << report;
  EXPECT_NE(report.find("| 3 | retract | surgeon |"), std::string::npos) << report;
  for (const auto& m : b.s.motions) {
    EXPECT_EQ(m.outcome, "arrived");
    EXPECT_GT(m.ended_s, m.approved_s);
  }
  // Home to the stylet's half step (the absolute end point is what is quantised).
  EXPECT_LE(std::abs(paperRobot()->transmission.toJoints(b.reading().position).z_s_mm),
            0.5 / paperRobot()->transmission.styletStepsPerMm() + 1e-12);
  EXPECT_EQ(b.sim().movesStarted(), moves);
}

// Found by the soak (tools/bench/bench_load.sh soak): the coupled transmission brings the stylet
// home as zs = -0.17 µm, and every later plan was refused as starting outside the stylet travel.
TEST(Approval, AFinishedInsertionIsFollowedByAnother) {
  // A target whose retraction quantisation alone leaves the stylet just behind its home (the
  // coupling turns the stylet nut with the cannula's rotation).
  const auto& tr = paperRobot()->transmission;
  kinematics::Joints behind{0.0, 12.0, 25.0};
  for (int deg = 0; deg < 360; ++deg) {
    behind.theta_c_rad = deg * M_PI / 180.0;
    kinematics::Joints home = tr.toJoints(tr.toSteps(behind).steps);
    home.z_s_mm = 0.0;
    if (tr.toJoints(tr.toSteps(home).steps).z_s_mm < 0.0) break;
  }
  Bench b;
  for (int insertion = 0; insertion < 3; ++insertion) {
    SCOPED_TRACE("insertion " + std::to_string(insertion));
    if (insertion > 0) {
      ASSERT_TRUE(b.send(b.command(InputKind::kUnlockPlan)).accepted);
      ASSERT_TRUE(b.send(b.command(InputKind::kClearTargets)).accepted);
    }
    b.addRobotTarget(insertion % 2 ? kJointsB : behind);
    const auto locked = b.send(b.command(InputKind::kLockPlan));
    ASSERT_TRUE(locked.accepted) << locked.message;
    for (int m = 0; m < 2; ++m) {
      ASSERT_TRUE(b.send(b.approvePending()).accepted);
      b.runMotion();
    }
    ASSERT_EQ(b.s.phase, Phase::kDone) << b.s.fault;
    // Quantisation alone leaves the stylet just behind its home: the case this is about.
    if (insertion == 0) {
      EXPECT_LT(paperRobot()->transmission.toJoints(b.reading().position).z_s_mm, 0.0);
    }
  }
}

TEST(Approval, EveryBadApprovalIsRefusedAndNothingMoves) {
  Bench b;
  b.addRobotTarget(kJointsA);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  const auto p = b.s.pending.value();
  const auto revision = b.s.revision;
  struct Case {
    Input in;
    std::string code;
  };
  std::vector<Case> cases = {
      {b.approve(p.plan_id, p.digest, "intern"), "not_approver"},
      {b.approve(p.plan_id + 1, p.digest), "stale_plan"},
      {b.approve(p.plan_id - 1, p.digest), "stale_plan"},
      {b.approve(p.plan_id, p.digest.substr(0, 63) + "0"), "wrong_digest"},
      {b.approve(p.plan_id, ""), "wrong_digest"},
      {b.approve(p.plan_id, std::string(200, 'a')), "too_long"},
  };
  Input late = b.approve(p.plan_id, p.digest);
  Input moved = b.approve(p.plan_id, p.digest);
  moved.controller = b.reading();
  moved.controller->position.motor[1] += 3;  // someone jogged a motor
  Input busy = b.approve(p.plan_id, p.digest);
  busy.controller = b.reading();
  busy.controller->state = ControllerState::kMoving;
  Input lost = b.approve(p.plan_id, p.digest);
  lost.controller = ControllerStatus{};  // disconnected
  cases.push_back({moved, "controller_changed"});
  cases.push_back({busy, "controller_busy"});
  cases.push_back({lost, "controller_unavailable"});
  for (auto& c : cases) {
    const auto r = b.send(c.in);
    EXPECT_FALSE(r.accepted);
    EXPECT_EQ(r.error_code, c.code) << r.message;
    EXPECT_FALSE(r.message.empty());
    EXPECT_EQ(b.s.revision, revision);
    EXPECT_EQ(b.s.phase, Phase::kPlanLocked);
  }
  b.t = p.expires_s + 0.5;
  const auto r = b.send(late);
  EXPECT_EQ(r.error_code, "expired") << r.message;
  EXPECT_EQ(b.sim().movesStarted(), 0u);
  // A fresh request works; the old plan id is stale from then on.
  ASSERT_TRUE(b.send(b.command(InputKind::kRequestApproval)).accepted);
  EXPECT_GT(b.s.pending.value().plan_id, p.plan_id);
  EXPECT_EQ(b.send(b.approve(p.plan_id, p.digest)).error_code, "stale_plan");
  EXPECT_TRUE(b.send(b.approvePending()).accepted);
  EXPECT_EQ(b.sim().movesStarted(), 1u);
}

TEST(Approval, AnApprovalIsUsedOnceAndDiesWithAnyChange) {
  Bench b;
  const auto id = b.addRobotTarget(kJointsA);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  const auto first = b.s.pending.value();
  // Unlock, move the target, lock again: the old approval names a dead plan.
  ASSERT_TRUE(b.send(b.command(InputKind::kUnlockPlan)).accepted);
  EXPECT_FALSE(b.s.pending.has_value());
  const Eigen::Vector3d tip = paperRobot()->kinematics.forward(kJointsB).tip_mm;
  ASSERT_TRUE(
      b.send(b.command(InputKind::kMoveTarget, {b.s.registration->toImage(tip)}, {id})).accepted);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  EXPECT_EQ(b.send(b.approve(first.plan_id, first.digest)).error_code, "stale_plan");
  EXPECT_NE(b.s.pending.value().digest, first.digest);
  // Used once: the same request id is answered from memory, a new one finds no pending plan.
  Input ok = b.approvePending();
  ASSERT_TRUE(b.send(ok).accepted);
  const auto again = b.send(ok);
  EXPECT_TRUE(again.accepted);  // the same answer, not a second execution
  Input replay = b.approve(ok.plan_id, ok.digest);
  EXPECT_EQ(b.send(replay).error_code, "wrong_phase");
  EXPECT_EQ(b.sim().movesStarted(), 1u);
  b.runMotion();
  EXPECT_EQ(b.s.phase, Phase::kAtTarget);
  EXPECT_EQ(b.send(b.approve(ok.plan_id, ok.digest)).error_code, "stale_plan");
}

TEST(Approval, ARestartNeverReArmsAnApproval) {
  Bench b;
  b.addRobotTarget(kJointsA);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  const auto before = b.s.pending.value();
  // The crash: a new session from the journal, then the server's restart input. (Request ids
  // that the journal's client has not used, so nothing is answered from memory.)
  Bench restarted(1000);
  auto recovered = replayJournal(
      newSession("bench", paperRobot(), "robot.yaml"), b.journal,
      [](const std::string&) -> Expected<LoadedCt> {
        LoadedCt ct;
        ct.volume = test::phantomCtGrid(*paperRobot());
        return ct;
      },
      "journal.jsonl");
  ASSERT_TRUE(recovered.ok()) << recovered.error().message;
  restarted.s = *recovered;
  restarted.feed(Bench::internal(InputKind::kServerRestarted));
  EXPECT_EQ(restarted.s.phase, Phase::kPlanLocked);
  ASSERT_TRUE(restarted.s.pending.has_value());
  EXPECT_NE(restarted.s.pending->plan_id, before.plan_id);
  const auto r = restarted.send(restarted.approve(before.plan_id, before.digest));
  EXPECT_EQ(r.error_code, "stale_plan") << r.message;
  EXPECT_EQ(restarted.sim().movesStarted(), 0u);
}

TEST(Approval, EmergencyStopMidMoveHaltsFirstThenResetChecksThePosition) {
  Bench b;
  const auto id = b.addRobotTarget(kJointsB);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  ASSERT_TRUE(b.send(b.approvePending()).accepted);
  for (int i = 0; i < 15; ++i)
    b.advance(0.01);
  ASSERT_EQ(b.reading().state, ControllerState::kMoving);
  const auto step = b.feed(b.command(InputKind::kEmergencyStop));
  ASSERT_FALSE(step.effects.controller.empty());
  EXPECT_EQ(step.effects.controller.front().action(), ControllerAction::kAbort);
  EXPECT_EQ(b.s.phase, Phase::kEmergency);
  // Halted at once: the same position a control period later.
  const auto halted = b.reading();
  EXPECT_EQ(halted.state, ControllerState::kIdle);
  b.advance(0.01);
  EXPECT_EQ(b.reading().position, halted.position);
  EXPECT_EQ(b.send(b.command(InputKind::kResume)).error_code, "wrong_phase");
  // The position lies on the interrupted move: reset accepts it and resume plans from there.
  ASSERT_TRUE(b.send(b.command(InputKind::kResetEmergency)).accepted);
  EXPECT_EQ(b.s.position, halted.position);
  const auto resumed = b.send(b.command(InputKind::kResume));
  ASSERT_TRUE(resumed.accepted) << resumed.message;
  EXPECT_EQ(b.s.phase, Phase::kPlanLocked);
  EXPECT_EQ(b.s.pending.value().from, halted.position);
  ASSERT_TRUE(b.send(b.approvePending()).accepted);
  b.runMotion();
  ASSERT_EQ(b.s.phase, Phase::kAtTarget) << b.s.fault;
  EXPECT_EQ(b.reading().position,
            paperRobot()->transmission.toSteps(b.target(id).solution.joints).steps);
}

TEST(Approval, StopMidMoveDeceleratesAndResumeNeedsANewApproval) {
  Bench b;
  b.addRobotTarget(kJointsB);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  ASSERT_TRUE(b.send(b.approvePending()).accepted);
  b.advance(0.05);
  const auto step = b.feed(b.command(InputKind::kStop));
  EXPECT_EQ(step.effects.controller.front().action(), ControllerAction::kStop);
  EXPECT_EQ(b.s.phase, Phase::kStopped);
  // Still decelerating: resume waits for rest.
  if (b.reading().state == ControllerState::kMoving) {
    EXPECT_EQ(b.send(b.command(InputKind::kResume)).error_code, "controller_busy");
  }
  b.t += 1.0;
  const auto moves = b.sim().movesStarted();
  ASSERT_TRUE(b.send(b.command(InputKind::kResume)).accepted);
  EXPECT_EQ(b.s.phase, Phase::kPlanLocked);
  EXPECT_EQ(b.sim().movesStarted(), moves);  // nothing moves before the new approval
}

TEST(Approval, ControllerFaultMidMoveBecomesTheFaultPhaseWithItsReason) {
  Bench b;
  b.addRobotTarget(kJointsB);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  b.sim().inject(actuation::InjectedFault::kStall, 0);  // the cannula screw motor
  ASSERT_TRUE(b.send(b.approvePending()).accepted);
  b.runMotion();
  ASSERT_EQ(b.s.phase, Phase::kFault);
  EXPECT_NE(b.s.fault.find("motor 1 stalled"), std::string::npos) << b.s.fault;
  EXPECT_EQ(b.send(b.approve(1, "x")).error_code, "wrong_phase");
  // A stop is always taken (issue 25): it halts the controller again; the fault stays.
  const auto stop = b.feed(b.command(InputKind::kStop));
  ASSERT_TRUE(stop.effects.replies.at(0).accepted);
  ASSERT_FALSE(stop.effects.controller.empty());
  EXPECT_TRUE(stop.effects.controller.front().isHalt());
  EXPECT_EQ(b.s.phase, Phase::kFault);
  // Stalled halfway along its move: the position check accepts it, then resume re-plans from
  // there and the new plan reaches the target.
  const auto r = b.send(b.command(InputKind::kResetEmergency));
  ASSERT_TRUE(r.accepted) << r.message;
  const auto resumed = b.send(b.command(InputKind::kResume));
  ASSERT_TRUE(resumed.accepted) << resumed.message;
  EXPECT_EQ(b.s.phase, Phase::kPlanLocked);
  ASSERT_TRUE(b.send(b.approvePending()).accepted);
  b.runMotion();
  EXPECT_EQ(b.s.phase, Phase::kAtTarget) << b.s.fault;
}

TEST(Approval, APoseOutsideTheJointRangesIsNotPlannedFromUntilHomed) {
  Bench b;
  b.addRobotTarget(kJointsB);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  // The stylet motor stalls while it follows the cannula's translation: the stylet ends up
  // behind its home (z_s < 0), a pose no plan may start from.
  b.sim().inject(actuation::InjectedFault::kStall, 2);
  ASSERT_TRUE(b.send(b.approvePending()).accepted);
  b.runMotion();
  ASSERT_EQ(b.s.phase, Phase::kFault);
  EXPECT_NE(b.s.fault.find("motor 3 stalled"), std::string::npos) << b.s.fault;
  ASSERT_TRUE(b.send(b.command(InputKind::kResetEmergency)).accepted);
  const auto refused = b.send(b.command(InputKind::kResume));
  EXPECT_EQ(refused.error_code, "plan_failed");
  EXPECT_NE(refused.message.find("outside the stylet travel"), std::string::npos)
      << refused.message;
  EXPECT_EQ(b.s.phase, Phase::kStopped);
  ASSERT_TRUE(b.send(b.command(InputKind::kHome)).accepted);
  ASSERT_TRUE(b.send(b.command(InputKind::kResume)).accepted);
  EXPECT_EQ(b.s.pending.value().from, Steps{});
}

TEST(Approval, ArrivalCheckCatchesAPositionMismatchAndOnlyHomingClearsIt) {
  Bench b;
  b.addRobotTarget(kJointsA);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  b.sim().inject(actuation::InjectedFault::kPositionMismatch, 0);
  ASSERT_TRUE(b.send(b.approvePending()).accepted);
  b.runMotion();
  ASSERT_EQ(b.s.phase, Phase::kFault);
  EXPECT_NE(b.s.fault.find("arrival check failed"), std::string::npos) << b.s.fault;
  EXPECT_NE(b.s.fault.find("motor 1 reads"), std::string::npos) << b.s.fault;
  const auto refused = b.send(b.command(InputKind::kResetEmergency));
  EXPECT_EQ(refused.error_code, "position_mismatch") << refused.message;
  // The operator brings the robot home by hand and says so; then the check passes.
  ASSERT_TRUE(b.send(b.command(InputKind::kHome)).accepted);
  ASSERT_TRUE(b.send(b.command(InputKind::kResetEmergency)).accepted);
  EXPECT_EQ(b.s.position, Steps{});
}

TEST(Approval, UserOrderBeyondTheRotationLimitIsRefusedServerOrderIsNot) {
  Bench b;
  // θc 350°, 10°, 345° in that order turns 350° + 340° + 335° from θc = 0.
  const kinematics::Joints j350{-10.0 * M_PI / 180.0, 10.0, 25.0};
  const kinematics::Joints j10{10.0 * M_PI / 180.0, 12.0, 30.0};
  const kinematics::Joints j345{-15.0 * M_PI / 180.0, 5.0, 20.0};
  const auto a = b.addRobotTarget(j350);
  const auto c = b.addRobotTarget(j10);
  const auto d = b.addRobotTarget(j345);
  ASSERT_TRUE(b.send(b.command(InputKind::kReorderTargets, {}, {a, c, d})).accepted);
  const auto refused = b.send(b.command(InputKind::kLockPlan));
  EXPECT_EQ(refused.error_code, "rotation_limit") << refused.message;
  EXPECT_NE(refused.message.find("1025.0°"), std::string::npos) << refused.message;
  EXPECT_EQ(b.s.phase, Phase::kPlanning);
  // Without a user order the server sweeps 10°, 345°, 350°: 350° in all.
  ASSERT_TRUE(b.send(b.command(InputKind::kClearTargets)).accepted);
  const auto a2 = b.addRobotTarget(j350);
  const auto c2 = b.addRobotTarget(j10);
  const auto d2 = b.addRobotTarget(j345);
  const auto ok = b.send(b.command(InputKind::kLockPlan));
  ASSERT_TRUE(ok.accepted) << ok.message;
  // Whatever order it chose (it also weighs time), count its rotation from the joints.
  double rotation_deg = 0.0, at = 0.0;
  std::set<std::uint32_t> ids;
  for (const auto& t : b.s.targets) {
    rotation_deg += std::abs(t.solution.joints.theta_c_rad - at) * 180.0 / M_PI;
    at = t.solution.joints.theta_c_rad;
    ids.insert(t.id);
  }
  EXPECT_EQ(ids, (std::set<std::uint32_t>{a2, c2, d2}));
  EXPECT_LE(rotation_deg, 360.0 + 1e-9);
  EXPECT_NE(ok.message.find(fmt::format("cannula rotation {:.1f}°", rotation_deg)),
            std::string::npos)
      << ok.message;
}

TEST(Approval, AnApproverListedByCertificateSubjectApprovesWhateverItsClientIdAndIsJournaled) {
  Bench b;
  const std::string subject = "CN=approver,O=ignav,C=NL";
  b.s.policy.approvers = {"surgeon", subject};
  b.addRobotTarget(kJointsA);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  const auto p = b.s.pending.value();
  // Neither the client id nor the identity listed: refused, and the message names both.
  Input stranger = b.approve(p.plan_id, p.digest, "console");
  stranger.identity = "CN=planner,O=ignav,C=NL";
  const auto refused = b.send(stranger);
  EXPECT_EQ(refused.error_code, "not_approver");
  EXPECT_NE(refused.message.find("CN=planner"), std::string::npos) << refused.message;
  // The identity listed, any client id: accepted, and the journal keeps who and through what.
  Input approver = b.approve(p.plan_id, p.digest, "console");
  approver.identity = subject;
  approver.role = "approver";
  const auto journal_before = b.journal.size();
  ASSERT_TRUE(b.send(approver).accepted);
  ASSERT_GT(b.journal.size(), journal_before);
  const auto entry = parseJournalRecord(b.journal.at(journal_before));
  ASSERT_TRUE(entry.ok());
  EXPECT_EQ(entry->input.kind, InputKind::kApprove);
  EXPECT_EQ(entry->input.identity, subject);
  EXPECT_EQ(entry->input.role, "approver");
  EXPECT_EQ(entry->input.client_id, "console");
  EXPECT_EQ(b.s.motions.back().approved_by, subject);
}

TEST(Approval, ThePlansTargetLimitComesFromThePolicyAndIsJournaled) {
  Bench b;
  ApprovalPolicy p = policy();
  p.limits.max_targets = 2;
  Session s = newSession("limits", paperRobot(), "robot.yaml");
  Input config = Bench::internal(InputKind::kConfigLoaded);
  config.policy = p;
  auto step = reduce(s, config);
  const auto entry = parseJournalRecord(step.effects.journal.at(0));
  ASSERT_TRUE(entry.ok());
  EXPECT_EQ(entry->input.policy.value().limits.max_targets, 2u);
  EXPECT_EQ(entry->input.policy->approvers, p.approvers);
  b.s.policy.limits.max_targets = 2;
  b.addRobotTarget(kJointsA);
  b.addRobotTarget(kJointsB);
  const Eigen::Vector3d tip = paperRobot()->kinematics.forward(kJointsC).tip_mm;
  const auto r = b.send(b.command(InputKind::kAddTarget, {b.s.registration->toImage(tip)}));
  EXPECT_EQ(r.error_code, "too_many_targets") << r.message;
  EXPECT_NE(r.message.find("2 targets"), std::string::npos) << r.message;
}

TEST(Deflection, TargetsCarryTheCannulaDriftTheSessionsTissuePredicts) {
  // With the plain model ("none": λ = 0) the drift after zc mm is the circle's (1 − cos k zc)/k.
  config::TissueProfile none;
  none.name = "none";
  none.needle = {-1.0 / 400.0, 20.0, -1};
  Session s = newSession("tissue", paperRobot(), "robot.yaml");
  Input config = Bench::internal(InputKind::kConfigLoaded);
  config.policy = policy();
  config.tissue = none;
  auto step = reduce(s, config);
  // The profile travels in the journal, so a replay predicts the same.
  const auto entry = parseJournalRecord(step.effects.journal.at(0));
  ASSERT_TRUE(entry.ok()) << entry.error().message;
  ASSERT_TRUE(entry->input.tissue.has_value());
  EXPECT_EQ(entry->input.tissue->name, "none");
  EXPECT_EQ(entry->input.tissue->needle.curvature_per_mm, -1.0 / 400.0);

  Bench b;
  EXPECT_TRUE(std::isnan(b.target(b.addRobotTarget(kJointsA)).predicted_deviation_mm));
  b.s.tissue = none;
  const auto id = b.addRobotTarget(kJointsB);
  // A copy: adding targets below may move the session's vector (ASan found the reference).
  const Target t = b.target(id);
  const double k = none.needle.curvature_per_mm, zc = t.solution.joints.z_c_mm;
  EXPECT_NEAR(t.predicted_deviation_mm, (1.0 - std::cos(k * zc)) / k, 1e-9);
  // Agar drifts differently, and the report labels the number as a model's.
  b.s.tissue->name = "agar";
  b.s.tissue->tissue = {0.49, 0.22};
  const auto agar = b.addRobotTarget(kJointsB);
  EXPECT_GT(std::abs(b.target(agar).predicted_deviation_mm - t.predicted_deviation_mm), 0.01);
  EXPECT_NE(procedureReport(b.s).find("model prediction"), std::string::npos);
}

// Random command sequences, adversarial approvals included, against an independent account of
// what may move: every motor command must follow an approve that named the pending plan's id and
// digest, from an approver, before expiry, with nothing accepted in between; and the number of
// moves the controller ever started never exceeds what such approvals released.
TEST(Approval, RandomSequencesNeverMoveWithoutAValidApproval) {
  std::size_t approvals_accepted = 0, approvals_refused = 0, moves_started = 0;
  for (unsigned seed = 1; seed <= 40; ++seed) {
    std::mt19937 rng(seed);
    Bench b;
    auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
    std::size_t released = 0;
    std::optional<MotionRequest> shown;  // the request as a client last saw it
    std::uint64_t shown_at_revision = 0;
    for (int i = 0; i < 120; ++i) {
      const auto phase_before = b.s.phase;
      const auto revision_before = b.s.revision;
      const auto moves_before = b.sim().movesStarted();
      Input in;
      bool valid_approval = false;
      // Mostly what an operator would do next, with everything else mixed in.
      int choice = pick(14);
      if (shown && pick(2) == 0) choice = 5;  // a request is showing: approve it, or twist it
      if (b.s.phase == Phase::kMoving && pick(2) == 0) choice = 12;  // let it move
      if (b.s.phase == Phase::kStopped && pick(2) == 0) choice = 9;  // resume
      if ((b.s.phase == Phase::kEmergency || b.s.phase == Phase::kFault) && pick(2) == 0) {
        choice = 11;  // reset (or home)
      }
      if (b.s.phase == Phase::kPlanning && pick(3) == 0) choice = pick(2) == 0 ? 0 : 3;
      if ((choice == 8 || choice == 10) && pick(2) == 0) choice = 13;  // fewer stops
      switch (choice) {
        case 0:
        case 1: {
          const kinematics::Joints j{(pick(360) - 180) * M_PI / 180.0, 1.0 * pick(40),
                                     1.0 * pick(40)};
          const Eigen::Vector3d tip = paperRobot()->kinematics.forward(j).tip_mm;
          in = b.command(InputKind::kAddTarget, {b.s.registration->toImage(tip)});
          break;
        }
        case 2:
          in = b.command(InputKind::kRemoveTarget, {}, {static_cast<std::uint32_t>(pick(6))});
          break;
        case 3:
          in = b.command(InputKind::kLockPlan);
          break;
        case 4:
          in = b.command(InputKind::kUnlockPlan);
          break;
        case 5:
        case 6: {
          // An approval: sometimes right, mostly subtly wrong.
          if (!shown) {
            in = b.approve(static_cast<std::uint64_t>(pick(5)), "00");
            break;
          }
          in = b.approve(shown->plan_id, shown->digest);
          const int twist = pick(5);
          if (twist == 1) in.plan_id += 1;
          if (twist == 2) in.digest[static_cast<std::size_t>(pick(64))] ^= 1;
          if (twist == 3) in.client_id = "visitor";
          valid_approval = twist == 0 || twist == 4;
          break;
        }
        case 7:
          in = b.command(InputKind::kRequestApproval);
          break;
        case 8:
          in = b.command(InputKind::kStop);
          break;
        case 9:
          in = b.command(InputKind::kResume);
          break;
        case 10:
          in = b.command(InputKind::kEmergencyStop);
          break;
        case 11:
          in = b.command(pick(3) == 0 ? InputKind::kHome : InputKind::kResetEmergency);
          break;
        case 12:
          for (int k = pick(80); k > 0; --k)
            b.advance(0.01);
          b.t += pick(3) == 0 ? 70.0 : 0.0;  // sometimes past an approval's expiry
          continue;
        default:
          if (pick(4) == 0) b.sim().inject(actuation::InjectedFault::kStall, pick(3));
          b.advance(0.01);
          continue;
      }
      const auto step = b.feed(in);
      const bool accepted = !step.effects.replies.empty() && step.effects.replies[0].accepted;
      const bool started = b.sim().movesStarted() > moves_before;
      if (in.kind == InputKind::kApprove && accepted) {
        // The independent account: the request shown, unchanged since, approved as shown.
        ASSERT_TRUE(valid_approval) << "seed " << seed << " step " << i;
        ASSERT_TRUE(shown.has_value());
        EXPECT_EQ(revision_before, shown_at_revision) << "seed " << seed << " step " << i;
        EXPECT_EQ(in.digest, requestDigest(scopeOf(b.s), *shown));
        EXPECT_LE(in.time_s, shown->expires_s);
        EXPECT_EQ(in.client_id, "surgeon");
        EXPECT_TRUE(phase_before == Phase::kPlanLocked || phase_before == Phase::kAtTarget);
        released += shown->moves.size();
        ++approvals_accepted;
        shown.reset();
      } else {
        if (in.kind == InputKind::kApprove) ++approvals_refused;
        EXPECT_FALSE(started) << toString(in.kind) << " started a move; seed " << seed;
      }
      EXPECT_LE(b.sim().movesStarted(), released) << "seed " << seed << " step " << i;
      if (b.s.pending && (!shown || shown->plan_id != b.s.pending->plan_id)) {
        shown = b.s.pending;
        shown_at_revision = b.s.revision;
      } else if (!b.s.pending) {
        shown.reset();
      }
    }
    moves_started += b.sim().movesStarted();
  }
  // The sequences did exercise motion, not only refusals.
  EXPECT_GT(approvals_accepted, 100u);
  EXPECT_GT(approvals_refused, 300u);
  EXPECT_GT(moves_started, 250u);
  std::cout << approvals_accepted << " approvals accepted, " << approvals_refused << " refused, "
            << moves_started << " moves started\n";
}

// Manual control (the BRP MANUAL workphase): halts first, refuses computer control, and resume
// takes over wherever the hands left the motors.
TEST(Manual, HaltsRefusesMotionAndResumeAdoptsThePosition) {
  Bench b;
  const auto id = b.addRobotTarget({0.6, 20.0, 15.0});
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  ASSERT_TRUE(b.s.pending.has_value());
  const auto manual = b.feed(b.command(InputKind::kManual));
  ASSERT_TRUE(manual.effects.replies.at(0).accepted);
  EXPECT_EQ(b.s.phase, Phase::kManual);
  ASSERT_FALSE(manual.effects.controller.empty());
  EXPECT_TRUE(manual.effects.controller.front().isHalt());
  EXPECT_FALSE(b.s.pending.has_value());  // the approval request died with the change
  for (InputKind kind : {InputKind::kLockPlan, InputKind::kRequestApproval, InputKind::kCheckReady,
                         InputKind::kManual}) {
    auto in = b.command(kind);
    in.path = "robot";
    const auto r = b.send(in);
    EXPECT_EQ(r.error_code, "wrong_phase") << toString(kind);
  }
  // A stop button always stops (issue 25): the controller is halted again, manual control stays.
  const auto stop = b.feed(b.command(InputKind::kStop));
  ASSERT_TRUE(stop.effects.replies.at(0).accepted);
  ASSERT_FALSE(stop.effects.controller.empty());
  EXPECT_TRUE(stop.effects.controller.front().isHalt());
  EXPECT_EQ(b.s.phase, Phase::kManual);
  // Someone turns the cannula by hand, a tenth of a radian.
  const Steps hands = paperRobot()->transmission.toSteps({0.1, 0.0, 0.0}).steps;
  ASSERT_NE(hands, Steps{});
  (void)b.sim().placeAt(hands);
  const auto resumed = b.send(b.command(InputKind::kResume));
  ASSERT_TRUE(resumed.accepted) << resumed.message;
  EXPECT_EQ(b.s.position, hands);
  EXPECT_EQ(b.s.phase, Phase::kPlanLocked);
  // The fresh request starts where the robot now is.
  ASSERT_TRUE(b.s.pending.has_value());
  EXPECT_EQ(b.s.pending->from, hands);
  EXPECT_EQ(b.s.pending->target_id, id);
  // And the journal says so: replaying it gives the same session.
  auto replayed = replayJournal(
      newSession("bench", paperRobot(), "robot.yaml"), b.journal,
      [](const std::string&) -> Expected<LoadedCt> {
        LoadedCt ct;
        ct.volume = test::phantomCtGrid(*paperRobot());
        return ct;
      },
      "journal");
  ASSERT_TRUE(replayed.ok()) << replayed.error().message;
  EXPECT_EQ(replayed->phase, Phase::kPlanLocked);
  EXPECT_EQ(replayed->position, hands);
}

// Issue 27: resume leads back to the phase the first interruption left (a move in flight: a fresh
// request in plan_locked), whatever interruptions followed it: stop, manual, emergency then reset,
// in every order and nesting up to three deep. An accepted resume always leaves stopped or manual,
// and a second one is refused; a session can always continue.
TEST(Resume, EveryInterruptionSequenceReturnsToTheInterruptedPhase) {
  enum class Cut { kStop, kManual, kEmergency };
  const auto name = [](Cut c) {
    return c == Cut::kStop ? "stop" : c == Cut::kManual ? "manual" : "emergency+reset";
  };
  const auto load = [](Bench& b) {
    auto in = b.command(InputKind::kLoadVolume);
    in.path = "phantom:";
    ASSERT_TRUE(b.send(in).accepted);
  };
  const auto loaded = [](Bench& b) {
    Input in = Bench::internal(InputKind::kVolumeLoaded);
    in.job = b.s.ct_revision;
    in.loaded.volume = test::phantomCtGrid(*paperRobot());
    in.loaded.source = "phantom:";
    b.feed(in);
  };
  const auto approveAndRun = [](Bench& b) {
    ASSERT_TRUE(b.send(b.approvePending()).accepted);
    b.runMotion();
  };
  struct Setup {
    const char* name;
    std::function<void(Bench&)> reach;
    Phase at;        // where the setup leaves the workflow
    Phase expected;  // where resume leads
    bool finish_load_while_interrupted = false;
  };
  const Setup setups[] = {
      {"imaging, a load in flight", load, Phase::kImaging, Phase::kImaging},
      {"imaging, the load finishing meanwhile", load, Phase::kImaging, Phase::kRegistration, true},
      {"registration", [&](Bench& b) { load(b), loaded(b); }, Phase::kRegistration,
       Phase::kRegistration},
      {"planning", [](Bench&) {}, Phase::kPlanning, Phase::kPlanning},
      {"plan_locked",
       [](Bench& b) {
         b.addRobotTarget(kJointsA);
         ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
       },
       Phase::kPlanLocked, Phase::kPlanLocked},
      {"moving",
       [](Bench& b) {
         b.addRobotTarget(kJointsB);
         ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
         ASSERT_TRUE(b.send(b.approvePending()).accepted);
         b.advance(0.05);
       },
       Phase::kMoving, Phase::kPlanLocked},
      {"at_target",
       [&](Bench& b) {
         b.addRobotTarget(kJointsA);
         b.addRobotTarget(kJointsC);
         ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
         approveAndRun(b);
       },
       Phase::kAtTarget, Phase::kAtTarget},
      {"done",
       [&](Bench& b) {
         b.addRobotTarget(kJointsA);
         ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
         approveAndRun(b);  // to the target
         approveAndRun(b);  // the stylet back
       },
       Phase::kDone, Phase::kDone},
  };
  std::vector<std::vector<Cut>> sequences;
  for (int length = 1; length <= 3; ++length) {
    const int count = length == 1 ? 3 : length == 2 ? 9 : 27;
    for (int code = 0; code < count; ++code) {
      std::vector<Cut> sequence;
      for (int i = 0, c = code; i < length; ++i, c /= 3)
        sequence.push_back(static_cast<Cut>(c % 3));
      sequences.push_back(sequence);
    }
  }
  int runs = 0, uninterrupted = 0;
  for (const auto& setup : setups) {
    for (const auto& sequence : sequences) {
      std::string what = setup.name;
      for (Cut c : sequence)
        what += std::string(" > ") + name(c);
      SCOPED_TRACE(what);
      Bench b;
      setup.reach(b);
      ASSERT_EQ(b.s.phase, setup.at);
      for (Cut c : sequence) {
        b.t += 1.0;  // the robot comes to rest after each halt
        const InputKind kind = c == Cut::kStop     ? InputKind::kStop
                               : c == Cut::kManual ? InputKind::kManual
                                                   : InputKind::kEmergencyStop;
        const auto r = b.send(b.command(kind));
        if (!r.accepted) {  // not from here (manual while moving, stop while stopped ...)
          EXPECT_EQ(r.error_code, "wrong_phase") << r.message;
          continue;
        }
        if (c == Cut::kEmergency) {
          b.t += 1.0;
          const auto reset = b.send(b.command(InputKind::kResetEmergency));
          ASSERT_TRUE(reset.accepted) << reset.message;
        }
      }
      if (b.s.phase == setup.at) {  // nothing interrupted it: manual alone while moving
        ++uninterrupted;
        continue;
      }
      ASSERT_TRUE(b.s.phase == Phase::kStopped || b.s.phase == Phase::kManual)
          << toString(b.s.phase);
      if (setup.finish_load_while_interrupted) loaded(b);
      b.t += 1.0;
      const auto resumed = b.send(b.command(InputKind::kResume));
      ASSERT_TRUE(resumed.accepted) << resumed.message;
      EXPECT_EQ(b.s.phase, setup.expected) << toString(b.s.phase);
      if (setup.expected == Phase::kPlanLocked || setup.expected == Phase::kAtTarget) {
        EXPECT_TRUE(b.s.pending.has_value());  // a fresh request to approve
      }
      EXPECT_EQ(b.send(b.command(InputKind::kResume)).error_code, "wrong_phase");
      ++runs;
    }
  }
  EXPECT_EQ(uninterrupted, 3);  // manual, manual twice, manual thrice: refused while moving
  EXPECT_EQ(runs, 8 * 39 - 3);
}

// A readiness question changes nothing: no revision, no journal record, no lost approval.
TEST(CheckReady, AnswersWithoutChangingAnything) {
  Bench b;
  b.addRobotTarget({0.6, 20.0, 15.0});
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  const auto revision = b.s.revision;
  const auto plan = b.s.pending.value().plan_id;
  const auto lines = b.journal.size();
  auto ask = b.command(InputKind::kCheckReady);
  ask.path = "targeting";
  const auto r = b.send(ask);
  EXPECT_TRUE(r.accepted) << r.message;
  EXPECT_EQ(b.s.revision, revision);
  EXPECT_EQ(b.journal.size(), lines);
  ASSERT_TRUE(b.s.pending.has_value());
  EXPECT_EQ(b.s.pending->plan_id, plan);
  ask.path = "everything";
  ++ask.request_id;
  EXPECT_EQ(b.send(ask).error_code, "bad_arguments");
  // A controller that does not answer is not ready.
  ask.path = "robot";
  ++ask.request_id;
  ask.controller = ControllerStatus{};  // disconnected
  EXPECT_EQ(b.send(ask).error_code, "controller_unavailable");
}

TEST(CheckReady, TargetingNeedsARegistration) {
  Session s = newSession("t", paperRobot(), "robot.yaml");
  Input config;
  config.kind = InputKind::kConfigLoaded;
  s = reduce(s, config).session;
  Input ask;
  ask.kind = InputKind::kCheckReady;
  ask.client_id = "slicer";
  ask.request_id = 1;
  ask.path = "targeting";
  ask.controller = ControllerStatus{};
  ask.controller->state = ControllerState::kIdle;
  EXPECT_EQ(reduce(s, ask).effects.replies.at(0).error_code, "not_registered");
  ask.path = "robot";
  EXPECT_TRUE(reduce(s, ask).effects.replies.at(0).accepted);
}

// A registration computed elsewhere (Slicer's, as a matrix): the targets are judged by it, its
// TRE is unknown (no fiducials), a bad matrix changes nothing, and the journal keeps it exactly.
TEST(SetRegistration, AMatrixRegistersAndIsJournaledExactly) {
  Bench b;
  const auto id = b.addRobotTarget({0.6, 20.0, 15.0});
  const Eigen::Vector3d lps = b.target(id).lps_mm;
  const Eigen::Vector3d robot_before = b.target(id).robot_mm;
  Eigen::Matrix4d m = b.s.registration->imageToRobot();
  m.topRightCorner<3, 1>() += Eigen::Vector3d(0.5, -0.25, 1.0);  // the robot moved a little
  auto set = b.command(InputKind::kSetRegistration);
  set.matrix = m;
  const auto r = b.send(set);
  ASSERT_TRUE(r.accepted) << r.message;
  EXPECT_LT((b.target(id).robot_mm - (m * lps.homogeneous()).head<3>()).norm(), 1e-9);
  EXPECT_LT((b.target(id).robot_mm - robot_before - Eigen::Vector3d(0.5, -0.25, 1.0)).norm(), 1e-9);
  EXPECT_TRUE(std::isnan(b.target(id).tre_mm));
  const auto entry = parseJournalRecord(b.journal.back());
  ASSERT_TRUE(entry.ok()) << entry.error().message;
  ASSERT_TRUE(entry->input.matrix.has_value());
  EXPECT_EQ(*entry->input.matrix, m);  // bit for bit

  const auto revision = b.s.revision;
  Eigen::Matrix4d sheared = m;
  sheared(0, 1) += 0.1;
  set.matrix = sheared;
  ++set.request_id;
  EXPECT_EQ(b.send(set).error_code, "not_similarity");
  EXPECT_EQ(b.s.revision, revision);
  EXPECT_LT((b.target(id).robot_mm - (m * lps.homogeneous()).head<3>()).norm(), 1e-9);
  auto missing = b.command(InputKind::kSetRegistration);
  missing.request_id = 1000;  // (the sheared one took the next id)
  EXPECT_EQ(b.send(missing).error_code, "bad_arguments");
}

// Approval as a type (issue 22): only the approval check makes an ApprovedMotion, a move for the
// controller exists only as one move of one, and the executor's check holds for exactly those.
static_assert(!std::is_default_constructible_v<ApprovedMotion>);
static_assert(!std::is_constructible_v<ApprovedMotion, std::string, MotionRequest>);
static_assert(!std::is_default_constructible_v<ControllerCommand>);
static_assert(!std::is_constructible_v<ControllerCommand, ControllerAction>);

TEST(ApprovedMotionType, EveryMoveSentIsOneMoveOfTheIntactApprovalInOrder) {
  Bench b;
  b.addRobotTarget(kJointsA);
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  const MotionRequest shown = b.s.pending.value();
  auto step = b.feed(b.approvePending());
  ASSERT_EQ(step.effects.controller.size(), 1u);
  std::vector<ControllerCommand> sent = step.effects.controller;
  while (b.s.phase == Phase::kMoving) {
    b.t += 0.05;
    if (b.reading().state == ControllerState::kMoving) continue;
    step = b.feed(b.internal(InputKind::kSegmentDone));
    sent.insert(sent.end(), step.effects.controller.begin(), step.effects.controller.end());
  }
  EXPECT_EQ(b.s.phase, Phase::kAtTarget);
  ASSERT_EQ(sent.size(), shown.moves.size());
  for (std::size_t i = 0; i < sent.size(); ++i) {
    const auto& c = sent[i];
    EXPECT_EQ(c.action(), ControllerAction::kMove);
    EXPECT_TRUE(c.releasable()) << i;
    ASSERT_TRUE(c.approval().has_value());
    EXPECT_EQ(c.approval()->request().digest, shown.digest);
    EXPECT_EQ(c.approval()->request().plan_id, shown.plan_id);
    EXPECT_EQ(c.increments(), shown.moves[i].steps) << i;
    // The digest, recomputed independently over what is about to be sent, is the one approved.
    EXPECT_EQ(requestDigest(scopeOf(b.s), c.approval()->request()), shown.digest);
  }
  // Halts and the rest carry no approval and need none.
  EXPECT_TRUE(ControllerCommand::abort().releasable());
  EXPECT_FALSE(ControllerCommand::abort().approval().has_value());
}

}  // namespace
}  // namespace ignav::workflow
