// The transition table as rows with guards and actions (issue 22): its shape (every row acts, no
// row is dead), the guards of the inputs with several outcomes, and, along random sessions, that
// a row fires for every allowed input and that each outcome leaves what its phase needs.
#include <gtest/gtest.h>

#include <map>
#include <random>
#include <utility>

#include "ignav/workflow/reducer.hpp"
#include "workflow/bench.hpp"

namespace ignav::workflow {
namespace {

using rig::Bench;
using test::paperRobot;

std::string rowText(const Transition& t) {
  return std::string(toString(t.from)) + " --" + toString(t.input) + "--> " + toString(t.to) +
         " (" + t.why + ")";
}

// The rows of each (phase, input) pair, in table order.
std::map<std::pair<Phase, InputKind>, std::vector<const Transition*>> rowsByPair() {
  std::map<std::pair<Phase, InputKind>, std::vector<const Transition*>> pairs;
  for (const auto& t : transitionTable())
    pairs[{t.from, t.input}].push_back(&t);
  return pairs;
}

TEST(Transitions, EveryRowHasAnAction) {
  for (const auto& t : transitionTable())
    EXPECT_NE(t.action, nullptr) << rowText(t);
}

// Rows are tried in order and a row without a guard always fires: one before another row of its
// pair would leave that row dead. A pair whose rows all carry guards must cover every session by
// those guards alone; only resume's do (one guard per destination, from one function), and a new
// such pair should come with a test of its own.
TEST(Transitions, APairsRowWithoutAGuardComesLastSoNoRowIsDead) {
  for (const auto& [pair, rows] : rowsByPair()) {
    for (std::size_t i = 0; i + 1 < rows.size(); ++i) {
      EXPECT_NE(rows[i]->guard, nullptr) << rowText(*rows[i]) << " hides " << rowText(*rows[i + 1]);
    }
    if (rows.back()->guard) {
      EXPECT_EQ(pair.second, InputKind::kResume) << rowText(*rows.back());
    }
  }
}

Input resumeWith(const actuation::Steps& position) {
  Input in;
  in.kind = InputKind::kResume;
  in.client_id = "surgeon";
  actuation::ControllerStatus reading;
  reading.state = actuation::ControllerState::kIdle;
  reading.position = position;
  in.controller = reading;
  return in;
}

// Exactly one of resume's rows fires, the one for the phase the interruption left; a phase that
// waits for an approval with nothing left to move goes on to done.
TEST(Transitions, ResumesGuardsPickTheInterruptedPhaseOrDoneWhenNothingIsLeft) {
  Bench b;
  b.addRobotTarget({0.6, 20.0, 15.0});
  for (Phase interrupted : {Phase::kStopped, Phase::kManual}) {
    for (bool something_left : {true, false}) {
      Session s = b.s;
      if (!something_left) s.targets.clear();  // and the stylet is home
      s.phase = interrupted;
      for (Phase back : kResumePhases) {
        SCOPED_TRACE(std::string(toString(interrupted)) + " back to " + toString(back) +
                     (something_left ? "" : ", nothing left"));
        s.resume_phase = back;
        const Input in = resumeWith(s.position);
        int firing = 0;
        for (const auto& t : transitionTable()) {
          if (t.from == interrupted && t.input == InputKind::kResume) firing += t.guard(s, in);
        }
        EXPECT_EQ(firing, 1);
        const bool waits = back == Phase::kPlanLocked || back == Phase::kAtTarget;
        const Phase expected = waits && !something_left ? Phase::kDone : back;
        ASSERT_NE(firingTransition(s, in), nullptr);
        EXPECT_EQ(firingTransition(s, in)->to, expected);
        const Step step = reduce(s, in);
        ASSERT_TRUE(step.effects.replies.at(0).accepted) << step.effects.replies[0].message;
        EXPECT_EQ(step.session.phase, expected);
        EXPECT_EQ(step.session.pending.has_value(), waits && something_left);
      }
    }
  }
}

// fiducials_detected: markers that register lead out of registration; three in a line do not, and
// the session says why.
TEST(Transitions, DetectedMarkersRegisterOrFireTheirOwnRow) {
  Bench b;
  Session s = b.s;
  s.phase = Phase::kRegistration;
  s.detecting = 7;
  Input found = Bench::internal(InputKind::kFiducialsDetected);
  found.job = 7;
  found.points = s.registration->image_mm;
  ASSERT_EQ(found.points.size(), 3u);
  EXPECT_EQ(firingTransition(s, found)->to, Phase::kPlanning);
  EXPECT_EQ(reduce(s, found).session.phase, Phase::kPlanning);

  found.points = {{0, 0, 0}, {10, 0, 0}, {20, 0, 0}};
  EXPECT_EQ(firingTransition(s, found)->to, Phase::kRegistration);
  const Step step = reduce(s, found);
  EXPECT_EQ(step.session.phase, Phase::kRegistration);
  EXPECT_EQ(step.session.detecting, 0u);
  EXPECT_NE(step.session.registration_status.message.find("the markers found do not register"),
            std::string::npos)
      << step.session.registration_status.message;
}

// A target with the stylet not deployed (zs = 0): arriving there as the last target leaves no
// retraction to approve, so segment_done goes on to done (the guard nothingLeftAfterArrival).
TEST(Transitions, ArrivingAtTheLastTargetWithTheStyletHomeIsDone) {
  Bench b;
  const auto id = b.addRobotTarget({0.6, 20.0, 0.0});
  ASSERT_TRUE(b.send(b.command(InputKind::kLockPlan)).accepted);
  ASSERT_TRUE(b.send(b.approvePending()).accepted);
  b.runMotion();
  EXPECT_STREQ(toString(b.s.phase), "done") << b.s.fault;
  EXPECT_TRUE(b.target(id).reached);
  EXPECT_FALSE(b.s.pending.has_value());
}

// Along random sessions: for every input allowed in the phase some row fires (the guards miss no
// session they meet), and each outcome leaves what its phase needs: at_target a request to
// approve, done none (whichever of segment_done's and resume's rows led there).
TEST(Transitions, InRandomSessionsARowFiresForEveryAllowedInputAndOutcomesFitTheirPhase) {
  std::size_t steps = 0;
  std::map<Phase, int> visited;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    std::mt19937 rng(seed);
    auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
    Bench b;
    auto check = [&](const char* after, int i) {
      ++steps;
      ++visited[b.s.phase];
      const std::string where = std::string("after ") + after + " in " + toString(b.s.phase) +
                                "; seed " + std::to_string(seed) + " step " + std::to_string(i);
      if (b.s.phase == Phase::kDone) {
        EXPECT_FALSE(b.s.pending.has_value()) << where;
      }
      if (b.s.phase == Phase::kAtTarget) {
        EXPECT_TRUE(b.s.pending.has_value()) << where;
      }
      for (const auto& t : transitionTable()) {
        if (t.from != b.s.phase) continue;
        Input in = Bench::internal(t.input);
        in.client_id = "surgeon";
        in.time_s = b.t;
        if (needsControllerReading(t.input)) in.controller = b.reading();
        EXPECT_NE(firingTransition(b.s, in), nullptr) << rowText(t) << "; " << where;
      }
    };
    for (int i = 0; i < 150; ++i) {
      Input in;
      int choice = pick(12);
      if (b.s.pending && pick(2) == 0) choice = 3;                   // approve what is shown
      if (b.s.phase == Phase::kMoving && pick(2) == 0) choice = 11;  // let it move
      switch (choice) {
        case 0:
        case 1: {
          const kinematics::Joints j{(pick(360) - 180) * M_PI / 180.0, 1.0 * pick(40),
                                     pick(4) == 0 ? 0.0 : 1.0 * pick(40)};
          const Eigen::Vector3d tip = paperRobot()->kinematics.forward(j).tip_mm;
          in = b.command(InputKind::kAddTarget, {b.s.registration->toImage(tip)});
          break;
        }
        case 2:
          in = b.command(InputKind::kLockPlan);
          break;
        case 3:
          if (!b.s.pending) continue;
          in = b.approvePending();
          break;
        case 4:
          in = b.command(pick(2) ? InputKind::kStop : InputKind::kManual);
          break;
        case 5:
          in = b.command(InputKind::kResume);
          break;
        case 6:
          in = b.command(pick(2) ? InputKind::kEmergencyStop : InputKind::kResetEmergency);
          break;
        case 7:
          in = Bench::internal(pick(2) ? InputKind::kServerRestarted : InputKind::kControllerFault);
          break;
        case 8:
          in = b.command(pick(2) ? InputKind::kUnlockPlan : InputKind::kHome);
          break;
        default:
          if (pick(6) == 0) b.sim().inject(actuation::InjectedFault::kStall, pick(3));
          for (int k = pick(100); k > 0; --k) {
            b.advance(0.01);  // segment_done at each rest
            check("a tick", i);
          }
          continue;
      }
      b.feed(in);
      check(toString(in.kind), i);
    }
  }
  // The walk reached motion, its ends, interruptions and faults, not just planning.
  EXPECT_GT(steps, 5000u);
  for (Phase p : {Phase::kPlanLocked, Phase::kMoving, Phase::kAtTarget, Phase::kDone,
                  Phase::kStopped, Phase::kEmergency, Phase::kFault, Phase::kManual}) {
    EXPECT_GT(visited[p], 10) << toString(p);
  }
}

}  // namespace
}  // namespace ignav::workflow
