// The reducer without DDS: every (phase, input) pair is either a declared transition or a
// rejection that changes nothing; steps are deterministic; targets survive re-registration.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <fstream>
#include <set>
#include <sstream>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/workflow/reducer.hpp"
#include "support/phantom_ct.hpp"

namespace ignav::workflow {
namespace {

using test::paperRobot;

Input command(InputKind kind, std::uint64_t request, std::vector<Eigen::Vector3d> points = {},
              std::vector<std::uint32_t> ids = {}) {
  Input in;
  in.kind = kind;
  in.client_id = "test";
  in.request_id = request;
  in.points = std::move(points);
  in.ids = std::move(ids);
  in.path = kind == InputKind::kLoadVolume ? "phantom:" : "";
  return in;
}

Input internal(InputKind kind) {
  Input in;
  in.kind = kind;
  return in;
}

// The image points of the robot's feature points under a known pose: a registration a
// set_fiducials command can use without any CT.
std::vector<Eigen::Vector3d> clickedFeatures(double shift_mm = 0.0) {
  const auto robot = paperRobot();
  auto rp = registration::makeRobotPhantom(robot->kinematics, robot->config.registration.scan);
  auto points = rp.value().spec.fiducials_lps_mm;
  for (auto& p : points)
    p.x() += shift_mm;
  return points;
}

Session planningSession() {
  Session s = newSession("t", paperRobot(), "robot.yaml");
  s = reduce(s, internal(InputKind::kConfigLoaded)).session;
  s = reduce(s, command(InputKind::kLoadVolume, 1)).session;
  Input loaded = internal(InputKind::kVolumeLoaded);
  loaded.job = s.ct_revision;
  loaded.loaded.volume = test::phantomCtGrid(*paperRobot());
  loaded.loaded.source = "phantom:";
  s = reduce(s, loaded).session;
  s = reduce(s, command(InputKind::kSetFiducials, 2, clickedFeatures())).session;
  EXPECT_EQ(s.phase, Phase::kPlanning);
  return s;
}

TEST(Workflow, EveryPhaseInputPairIsATransitionOrARejectionThatChangesNothing) {
  for (Phase phase : kAllPhases) {
    for (const auto& spec : inputTable()) {
      const InputKind kind = spec.kind;
      if (!isCommand(kind)) continue;
      Session s = planningSession();
      s.phase = phase;
      const auto step = reduce(s, command(kind, 100));
      ASSERT_EQ(step.effects.replies.size(), 1u);
      const auto& reply = step.effects.replies[0];
      bool declared = false;
      for (const auto& t : transitionTable())
        declared |= t.from == phase && t.input == kind;
      if (!declared) {
        EXPECT_EQ(reply.error_code, "wrong_phase") << toString(phase) << " " << toString(kind);
        EXPECT_EQ(step.session.phase, phase);
        EXPECT_EQ(step.session.revision, s.revision);
        EXPECT_EQ(step.session.targets.size(), s.targets.size());
        EXPECT_TRUE(step.effects.journal.empty());
      } else {
        EXPECT_NE(reply.error_code, "wrong_phase") << toString(phase) << " " << toString(kind);
      }
    }
  }
}

TEST(Inputs, EachInputIsDeclaredOnceWithItsOwnNameAndWireKind) {
  std::set<std::string> names;
  std::set<std::int32_t> wire;
  std::size_t commands = 0;
  for (std::size_t i = 0; i < inputTable().size(); ++i) {
    const auto& spec = inputTable()[i];
    EXPECT_EQ(static_cast<std::size_t>(spec.kind), i) << spec.name;
    EXPECT_TRUE(names.insert(spec.name).second) << spec.name;
    EXPECT_TRUE(std::string(spec.help).size() > 10) << spec.name;
    if (spec.wire_kind != kNoWireKind) {
      EXPECT_TRUE(wire.insert(spec.wire_kind).second) << spec.name;
      EXPECT_TRUE(isCommand(spec.kind)) << spec.name;  // only clients send Commands
      EXPECT_EQ(commandOfWireKind(spec.wire_kind), &spec);
    }
    if (isCommand(spec.kind)) {
      ++commands;
      EXPECT_EQ(commandNamed(spec.name), &spec);
    } else {
      EXPECT_EQ(commandNamed(spec.name), nullptr) << spec.name << " is the server's own";
    }
  }
  EXPECT_EQ(commands, 40u);  // 39 on the Command topics, and approve on its own
  // The numbers clients built against the old IDL enum keep their meaning.
  EXPECT_EQ(commandNamed("load_volume")->wire_kind, 0);
  EXPECT_EQ(commandNamed("query")->wire_kind, 14);
  EXPECT_EQ(commandNamed("check_ready")->wire_kind, 19);
  EXPECT_EQ(commandNamed("approve")->wire_kind, kNoWireKind);
}

// Each command's row says what it carries; anything else is refused before it does anything.
TEST(Inputs, WhatACommandCarriesIsCheckedAgainstItsRow) {
  const Session s = planningSession();
  auto reject = [&](Input in) {
    const auto step = reduce(s, in);
    EXPECT_EQ(step.session.revision, s.revision);
    return step.effects.replies.at(0);
  };
  Input in = command(InputKind::kAddTarget, 50, {{1, 2, 3}, {4, 5, 6}});
  auto r = reject(in);
  EXPECT_EQ(r.error_code, "bad_arguments");
  EXPECT_EQ(r.message, "add_target takes 1 point(s) and 0 id(s); got 2 and 0");
  in = command(InputKind::kClearTargets, 51);
  in.path = "x";
  EXPECT_EQ(reject(in).message, "clear_targets takes no path");
  in = command(InputKind::kCheckReady, 52);
  in.path = "robot|targeting";
  r = reject(in);
  EXPECT_EQ(r.error_code, "bad_arguments");
  EXPECT_EQ(r.message, "check_ready's path is one of robot|targeting; got \"robot|targeting\"");
  in = command(InputKind::kSetRegistration, 53);
  EXPECT_EQ(reject(in).message, "set_registration needs a 4x4 matrix");
  in = command(InputKind::kAddTarget, 54, {{1, 2, 3}});
  in.matrix = Eigen::Matrix4d::Identity();
  EXPECT_EQ(reject(in).message, "add_target takes no matrix");
  // "Any number" of ids: reorder_targets takes a list, judged against the targets.
  in = command(InputKind::kReorderTargets, 55, {}, {7, 8, 9});
  EXPECT_EQ(reject(in).error_code, "bad_order");
}

TEST(ReplyCodes, EachCodeHasOneNameAndEveryRegistrationRefusalIsOne) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < replyCodeTable().size(); ++i) {
    const auto& c = replyCodeTable()[i];
    EXPECT_EQ(static_cast<std::size_t>(c.code), i) << c.name;
    EXPECT_TRUE(names.insert(c.name).second) << c.name;
    EXPECT_EQ(replyCodeNamed(c.name), c.code);
    EXPECT_GT(std::string(c.meaning).size(), 10u) << c.name;
  }
  EXPECT_FALSE(replyCodeNamed("no_such_code").has_value());
  // Refusals modules/registration gives reach the client under their own name, not "internal".
  const Session s = planningSession();
  auto refusal = [&](Input in) { return reduce(s, in).effects.replies.at(0).error_code; };
  Input collinear = command(InputKind::kSetFiducials, 70, {{0, 0, 0}, {10, 0, 0}, {20, 0, 0}});
  EXPECT_EQ(refusal(collinear), "collinear");
  Input mirror = command(InputKind::kSetRegistration, 71);
  mirror.matrix = Eigen::Matrix4d::Identity();
  (*mirror.matrix)(0, 0) = -1;
  EXPECT_EQ(refusal(mirror), "mirror");
  Input shear = command(InputKind::kSetRegistration, 72);
  shear.matrix = Eigen::Matrix4d::Identity();
  (*shear.matrix)(0, 1) = 0.5;
  EXPECT_EQ(refusal(shear), "not_similarity");
  Input last_row = command(InputKind::kSetRegistration, 73);
  last_row.matrix = Eigen::Matrix4d::Identity();
  (*last_row.matrix)(3, 0) = 1;
  EXPECT_EQ(refusal(last_row), "not_affine");
}

TEST(Inputs, PingAnswersWithTheServersTimeInEveryPhaseAndChangesNothing) {
  for (Phase phase : kAllPhases) {
    Session s = planningSession();
    s.phase = phase;
    s.pending = MotionRequest{};
    s.pending->plan_id = 77;
    Input ping = command(InputKind::kPing, 60);
    ping.time_s = 1764000000.25;
    const auto step = reduce(s, ping);
    const auto& reply = step.effects.replies.at(0);
    EXPECT_TRUE(reply.accepted) << toString(phase) << ": " << reply.message;
    EXPECT_EQ(reply.message,
              fmt::format("server_time_unix_s=1764000000.250000 revision={}", s.revision));
    EXPECT_EQ(reply.revision, s.revision);
    EXPECT_EQ(step.session.revision, s.revision);
    EXPECT_EQ(step.session.phase, phase);
    EXPECT_TRUE(step.effects.journal.empty());
    EXPECT_TRUE(step.effects.controller.empty());
    ASSERT_TRUE(step.session.pending.has_value()) << "a question must not kill a pending request";
    EXPECT_EQ(step.session.pending->plan_id, 77u);
  }
}

TEST(Workflow, EmergencyStopFromEveryPhaseAndOnlyResetLeavesIt) {
  for (Phase phase : kAllPhases) {
    Session s = planningSession();
    s.phase = phase;
    auto step = reduce(s, command(InputKind::kEmergencyStop, 7));
    if (phase == Phase::kEmergency) continue;  // already there
    EXPECT_EQ(step.session.phase, Phase::kEmergency) << toString(phase);
    EXPECT_FALSE(reduce(step.session, command(InputKind::kResume, 8)).effects.replies[0].accepted);
    // The robot is halted before anything else.
    ASSERT_FALSE(step.effects.controller.empty());
    EXPECT_EQ(step.effects.controller.front().action(), ControllerAction::kAbort);
    // Leaving needs a controller reading that passes the position check.
    auto reset = command(InputKind::kResetEmergency, 9);
    EXPECT_EQ(reduce(step.session, reset).effects.replies[0].error_code, "controller_unavailable");
    reset.controller = actuation::ControllerStatus{actuation::ControllerState::kIdle, {}, {}, ""};
    reset.controller->position.motor[0] = 5;
    EXPECT_EQ(reduce(step.session, reset).effects.replies[0].error_code, "position_mismatch");
    reset.controller->position.motor[0] = 0;
    step = reduce(step.session, reset);
    EXPECT_EQ(step.session.phase, Phase::kStopped);
  }
}

TEST(Workflow, StopAndResumeReturnToTheInterruptedPhase) {
  Session s = planningSession();
  s = reduce(s, command(InputKind::kStop, 10)).session;
  EXPECT_EQ(s.phase, Phase::kStopped);
  s = reduce(s, command(InputKind::kResume, 11)).session;
  EXPECT_EQ(s.phase, Phase::kPlanning);
}

TEST(Workflow, SameInputsGiveTheSameSessionsAndJournal) {
  auto run = [] {
    Session s = planningSession();
    std::vector<std::string> journal;
    for (std::uint32_t i = 0; i < 5; ++i) {
      auto step =
          reduce(s, command(InputKind::kAddTarget, 20 + i, {Eigen::Vector3d(1.0 * i, 2.0, 3.0)}));
      journal.insert(journal.end(), step.effects.journal.begin(), step.effects.journal.end());
      s = step.session;
    }
    return std::make_pair(s.revision, journal);
  };
  EXPECT_EQ(run(), run());
}

TEST(Workflow, TargetsAreReEvaluatedNotDroppedWhenTheRegistrationChanges) {
  Session s = planningSession();
  // The robot-frame point (8, 12, -175) is reachable; click where it lies in the image.
  const Eigen::Vector3d click = s.registration->toImage({8.0, 12.0, -175.0});
  auto step = reduce(s, command(InputKind::kAddTarget, 30, {click}));
  s = step.session;
  ASSERT_EQ(s.targets.size(), 1u);
  EXPECT_EQ(s.targets[0].status(), "planned");
  // Re-register with every image point 60 mm to the left: the same click is now 60 mm away in
  // the robot frame, so the target is re-derived (unreachable) but kept.
  step = reduce(s, command(InputKind::kSetFiducials, 31, clickedFeatures(60.0)));
  ASSERT_TRUE(step.effects.replies[0].accepted) << step.effects.replies[0].message;
  ASSERT_EQ(step.session.targets.size(), 1u);
  EXPECT_EQ(step.session.targets[0].id, s.targets[0].id);
  EXPECT_NEAR((step.session.targets[0].robot_mm - s.targets[0].robot_mm).norm(), 60.0, 1e-6);
  EXPECT_EQ(step.session.targets[0].status(), "unreachable");
  EXPECT_EQ(step.effects.targets_changed, std::vector<std::uint32_t>{s.targets[0].id});
}

TEST(Workflow, RepeatedRequestIsAnsweredFromMemory) {
  Session s = planningSession();
  const auto first = reduce(s, command(InputKind::kAddTarget, 40, {{1, 2, 3}}));
  const auto again = reduce(first.session, command(InputKind::kAddTarget, 40, {{1, 2, 3}}));
  EXPECT_EQ(again.session.targets.size(), 1u);
  EXPECT_TRUE(again.effects.journal.empty());
  EXPECT_EQ(again.effects.replies[0].target_id, first.effects.replies[0].target_id);
}

// Found by fuzz_command: a client id of raw bytes threw out of the journal's JSON and took the
// server down. Text fields must be UTF-8; the rest is refused with the byte that is wrong.
TEST(Workflow, TextThatIsNotUtf8IsRefusedAndNothingIsJournaled) {
  const Session s = planningSession();
  for (const std::string& bad : {std::string("op\xF5"), std::string("\xC0\xAF"),  // overlong '/'
                                 std::string("a\xED\xA0\x80"),                    // a surrogate
                                 std::string("\xE2\x82")}) {                      // cut short
    Input in = command(InputKind::kAddTarget, 7, {{1, 2, 3}});
    in.client_id = bad;
    auto step = reduce(s, in);
    ASSERT_EQ(step.effects.replies.size(), 1u);
    EXPECT_EQ(step.effects.replies[0].error_code, "bad_text");
    EXPECT_NE(step.effects.replies[0].message.find("client_id is not UTF-8"), std::string::npos)
        << step.effects.replies[0].message;
    EXPECT_TRUE(step.effects.journal.empty());
    EXPECT_EQ(step.session.revision, s.revision);
  }
  Input load = command(InputKind::kLoadVolume, 8);
  load.path =
      "/data/\xFF"
      "ct";
  const auto step = reduce(s, load);
  EXPECT_EQ(step.effects.replies.at(0).error_code, "bad_text");
  EXPECT_NE(step.effects.replies[0].message.find("path is not UTF-8 text (byte 6 is 0xFF)"),
            std::string::npos)
      << step.effects.replies[0].message;
  // Well-formed text of every length of sequence is taken.
  Input ok = command(InputKind::kAddTarget, 9, {{1, 2, 3}});
  ok.client_id = "op\xC3\xA9\xE2\x82\xAC\xF0\x9F\x92\x89";  // é € 💉
  EXPECT_TRUE(reduce(s, ok).effects.replies.at(0).accepted);
}

// Found by fuzz_command: a target 1e300 mm away printed past a fixed message buffer.
TEST(Workflow, CoordinatesBeyondAKilometreAreRefused) {
  const Session s = planningSession();
  const auto step = reduce(s, command(InputKind::kAddTarget, 7, {{1e300, 0, 0}}));
  EXPECT_EQ(step.effects.replies.at(0).error_code, "out_of_range");
  EXPECT_NE(step.effects.replies[0].message.find("points[0]"), std::string::npos);
  EXPECT_TRUE(step.effects.journal.empty());
  // Within the limit, a point is judged like any other: this one lies outside the CT.
  EXPECT_EQ(reduce(s, command(InputKind::kAddTarget, 8, {{999999, 0, 0}}))
                .effects.replies.at(0)
                .error_code,
            "outside_volume");
}

// Found by fuzz_journal: integer fields holding floats out of range were converted anyway
// (undefined behaviour); now the record is refused, naming the field.
TEST(Workflow, JournalIntegersAreCheckedNotCast) {
  const std::string good =
      R"({"input":"add_target","phase":"planning","revision":5,"t":1.0,"v":1,"client_id":"a",)"
      R"("request_id":3,"points":[[1,2,3]],"ids":[]})";
  ASSERT_TRUE(parseJournalRecord(good).ok());
  for (const auto& [from, to] :
       {std::pair<std::string, std::string>{"\"revision\":5", "\"revision\":1.8e22"},
        {"\"revision\":5", "\"revision\":-5"},
        {"\"request_id\":3", "\"request_id\":3.5"},
        {"\"ids\":[]", "\"ids\":[4294967296]"},
        {"\"v\":1", "\"v\":1e300"}}) {
    std::string bad = good;
    bad.replace(bad.find(from), from.size(), to);
    const auto parsed = parseJournalRecord(bad);
    EXPECT_FALSE(parsed.ok()) << bad;
  }
}

// A sender spraying client ids cannot grow the reply memory without end.
TEST(Workflow, RepliesAreRememberedForABoundedNumberOfClients) {
  Session s = planningSession();
  for (int i = 0; i < 1000; ++i) {
    Input in = command(InputKind::kQuery, 1);
    in.client_id = "spray-" + std::to_string(i);
    s = reduce(s, in).session;
  }
  EXPECT_LE(s.replies.size(), 256u);
  EXPECT_TRUE(s.replies.count("spray-999"));  // the latest is kept
}

TEST(Workflow, JournalRecordsReplayToTheSameSession) {
  // Run a session, keep its journal, then feed the parsed records to a fresh session.
  Session live = newSession("t", paperRobot(), "robot.yaml");
  std::vector<std::string> journal;
  auto run = [&](const Input& in) {
    auto step = reduce(live, in);
    journal.insert(journal.end(), step.effects.journal.begin(), step.effects.journal.end());
    live = step.session;
  };
  run(internal(InputKind::kConfigLoaded));
  run(command(InputKind::kLoadVolume, 1));
  Input loaded = internal(InputKind::kVolumeLoaded);
  loaded.job = live.ct_revision;
  loaded.loaded.volume = test::phantomCtGrid(*paperRobot());
  run(loaded);
  run(command(InputKind::kSetFiducials, 2, clickedFeatures()));
  run(command(InputKind::kAddTarget, 3, {{1.0 / 3.0, 19.1, -22.7}}));
  run(command(InputKind::kQuery, 4));  // not journaled
  run(command(InputKind::kStop, 5));
  ASSERT_EQ(journal.size(), 6u);

  Session replayed = newSession("t", paperRobot(), "robot.yaml");
  for (const auto& line : journal) {
    auto entry = parseJournalRecord(line);
    ASSERT_TRUE(entry.ok()) << entry.error().message << ": " << line;
    if (entry->input.kind == InputKind::kVolumeLoaded) entry->input.loaded = loaded.loaded;
    replayed = reduce(replayed, entry->input).session;
    EXPECT_EQ(replayed.revision, entry->revision);
    EXPECT_EQ(toString(replayed.phase), entry->phase);
  }
  EXPECT_EQ(replayed.phase, live.phase);
  ASSERT_EQ(replayed.targets.size(), 1u);
  // Bit-exact: the points went through the text at full precision.
  EXPECT_EQ(replayed.targets[0].lps_mm, live.targets[0].lps_mm);
  EXPECT_EQ(replayed.targets[0].solution.joints.z_s_mm, live.targets[0].solution.joints.z_s_mm);
  EXPECT_FALSE(parseJournalRecord("{\"v\":2}").ok());
  EXPECT_FALSE(parseJournalRecord("not json").ok());
}

// Issue 26: a target must lie in tissue the CT shows. The phantom grid is 128 x 128 x 112 voxels
// of 0.8 x 0.8 x 1.25 mm centred on LPS (0, 0, 0): the imaged box is +-51.2, +-51.2, +-70 mm.
TEST(Targets, PointsOutsideTheCtAreRefusedAndChangeNothing) {
  Session s = planningSession();
  s = reduce(s, command(InputKind::kAddTarget, 60, {{0.0, 0.0, -20.0}})).session;
  ASSERT_EQ(s.targets.size(), 1u);
  EXPECT_FALSE(s.targets[0].outside_volume);
  const struct {
    Eigen::Vector3d lps_mm;
    const char* outside_by;
  } outside[] = {{{0.0, 0.0, 75.0}, "5.0 mm"},      // past the top slice
                 {{51.3, 0.0, 0.0}, "0.1 mm"},      // just past a face
                 {{60.0, 0.0, -80.0}, "13.3 mm"}};  // past an edge: hypot(8.8, 10)
  for (const auto& o : outside) {
    const auto add = reduce(s, command(InputKind::kAddTarget, 61, {o.lps_mm}));
    const auto& reply = add.effects.replies.at(0);
    EXPECT_EQ(reply.error_code, "outside_volume") << o.lps_mm.transpose();
    EXPECT_NE(reply.message.find(o.outside_by), std::string::npos) << reply.message;
    EXPECT_NE(reply.message.find("phantom:"), std::string::npos) << reply.message;  // which CT
    EXPECT_EQ(add.session.targets.size(), 1u);
    EXPECT_EQ(add.session.revision, s.revision);
    EXPECT_TRUE(add.effects.journal.empty());
    const auto move = reduce(s, command(InputKind::kMoveTarget, 62, {o.lps_mm}, {1}));
    EXPECT_EQ(move.effects.replies.at(0).error_code, "outside_volume");
    EXPECT_EQ(move.session.targets[0].lps_mm, s.targets[0].lps_mm);
    EXPECT_EQ(move.session.revision, s.revision);
  }
  // Just inside a face is a target like any other.
  const auto inside = reduce(s, command(InputKind::kAddTarget, 63, {{51.1, 0.0, 0.0}}));
  EXPECT_TRUE(inside.effects.replies.at(0).accepted) << inside.effects.replies.at(0).message;
}

TEST(Targets, ACtThatMissesATargetLoadedLaterBlocksTheLock) {
  Session s = planningSession();
  const Eigen::Vector3d click = s.registration->toImage({8.0, 12.0, -175.0});
  s = reduce(s, command(InputKind::kAddTarget, 70, {click})).session;
  ASSERT_EQ(s.targets.at(0).status(), "planned");
  // Another CT, its grid 200 mm to the left of the phantom's: the target is not in it.
  s = reduce(s, command(InputKind::kLoadVolume, 71)).session;
  auto shifted = std::make_shared<volume::Volume>(*test::phantomCtGrid(*paperRobot()));
  shifted->geometry.origin_lps_mm.x() += 200.0;
  Input loaded = internal(InputKind::kVolumeLoaded);
  loaded.job = s.ct_revision;
  loaded.loaded.volume = shifted;
  auto step = reduce(s, loaded);
  s = step.session;
  EXPECT_TRUE(s.targets.at(0).outside_volume);
  EXPECT_EQ(s.targets.at(0).status(), "outside_volume");
  EXPECT_NE(std::find(step.effects.targets_changed.begin(), step.effects.targets_changed.end(),
                      s.targets[0].id),
            step.effects.targets_changed.end());
  s = reduce(s, command(InputKind::kSetFiducials, 72, clickedFeatures())).session;
  ASSERT_EQ(s.phase, Phase::kPlanning);
  EXPECT_EQ(s.targets.at(0).status(), "outside_volume");  // registered, still not imaged
  const auto lock = reduce(s, command(InputKind::kLockPlan, 73));
  EXPECT_EQ(lock.effects.replies.at(0).error_code, "outside_volume");
  EXPECT_NE(lock.effects.replies.at(0).message.find("target 1"), std::string::npos);
  EXPECT_EQ(lock.session.phase, Phase::kPlanning);
  EXPECT_FALSE(lock.session.pending.has_value());
}

// The path check: with the whole phantom grid the path to a reachable target stays inside it; with
// a CT that images only a 20 mm cube around the target, most of the path runs outside. The longest
// chord of a 20 mm cube is 20·sqrt(3) mm, so at least (path length - 34.7) mm lies outside, and
// the path is at least as long as the straight line from the tip at home to the target.
TEST(Targets, APathLeavingTheCtIsAWarningNotARefusal) {
  Session s = planningSession();
  const Eigen::Vector3d click = s.registration->toImage({8.0, 12.0, -175.0});
  s = reduce(s, command(InputKind::kAddTarget, 80, {click})).session;
  ASSERT_EQ(s.targets.at(0).status(), "planned");
  EXPECT_EQ(s.targets[0].path_outside_ct_mm, 0.0);
  EXPECT_TRUE(s.targets[0].path_warning.empty()) << s.targets[0].path_warning;

  s = reduce(s, command(InputKind::kLoadVolume, 81)).session;
  auto cube = std::make_shared<volume::Volume>();
  cube->geometry.dims = {20, 20, 20};
  cube->geometry.spacing_mm = Eigen::Vector3d::Ones();
  cube->geometry.origin_lps_mm = click - Eigen::Vector3d::Constant(9.5);  // centred on the target
  Input loaded = internal(InputKind::kVolumeLoaded);
  loaded.job = s.ct_revision;
  loaded.loaded.volume = cube;
  s = reduce(s, loaded).session;
  const auto added = reduce(s, command(InputKind::kSetFiducials, 82, clickedFeatures()));
  s = added.session;
  ASSERT_EQ(s.phase, Phase::kPlanning);
  const Target& t = s.targets.at(0);
  EXPECT_EQ(t.status(), "planned");
  ASSERT_FALSE(t.path_warning.empty());
  EXPECT_NE(t.message.find("warning: the planned path runs"), std::string::npos) << t.message;
  const auto path = needlePathLps(s, t.solution.joints);
  const double chord_mm = (path.back() - path.front()).norm();
  EXPECT_NEAR((path.back() - click).norm(), 0.0, 1e-6);  // the path ends at the target
  EXPECT_GE(t.path_outside_ct_mm, chord_mm - 20.0 * std::sqrt(3.0) - 0.5);
  EXPECT_LT(t.path_outside_ct_mm, chord_mm + 40.0);  // the arc is at most the stylet's 40 mm
  // A warning, not a refusal: the plan locks.
  const auto lock = reduce(s, command(InputKind::kLockPlan, 83));
  EXPECT_TRUE(lock.effects.replies.at(0).accepted) << lock.effects.replies.at(0).message;
}

TEST(Workflow, ReportTabulatesTheTargets) {
  Session s = planningSession();
  const Eigen::Vector3d click = s.registration->toImage({8.0, 12.0, -175.0});
  s = reduce(s, command(InputKind::kAddTarget, 50, {click})).session;
  s = reduce(s, command(InputKind::kAddTarget, 51, {s.registration->toImage({40, 0, -180})}))
          .session;
  const std::string report = procedureReport(s);
  const auto& j = s.targets[0].solution.joints;
  EXPECT_NE(report.find(fmt::format("| 1 | T1 | planned |")), std::string::npos) << report;
  EXPECT_NE(report.find(fmt::format("{:.3f}", j.z_s_mm)), std::string::npos) << report;
  EXPECT_NE(report.find("| 2 | T2 | unreachable |"), std::string::npos) << report;
  EXPECT_NE(report.find("beyond the maximum radius 26.535 mm"), std::string::npos) << report;
  EXPECT_NE(report.find("registration: similarity from 3 points"), std::string::npos) << report;
}

TEST(Workflow, DiagramInDocsIsCurrent) {
  std::ifstream in(IGNAV_SOURCE_DIR "/docs/WORKFLOW.md");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), workflowMarkdown())
      << "regenerate: build/tools/workflow-diagram/ignav-workflow-diagram > docs/WORKFLOW.md";
}

TEST(Workflow, CommandTableInProtocolDocIsCurrent) {
  std::ifstream in(IGNAV_SOURCE_DIR "/docs/PROTOCOL.md");
  std::stringstream text;
  text << in.rdbuf();
  const std::string generated = "<!-- commands: generated by ignav-workflow-diagram -->\n" +
                                commandsMarkdown() + "<!-- end of generated commands -->\n";
  const std::string codes = "<!-- reply codes: generated by ignav-workflow-diagram -->\n" +
                            replyCodesMarkdown() + "<!-- end of generated reply codes -->\n";
  EXPECT_NE(text.str().find(codes), std::string::npos)
      << "regenerate: build/tools/workflow-diagram/ignav-workflow-diagram --update-protocol "
         "docs/PROTOCOL.md";
  EXPECT_NE(text.str().find(generated), std::string::npos)
      << "regenerate: build/tools/workflow-diagram/ignav-workflow-diagram --update-protocol "
         "docs/PROTOCOL.md";
}

}  // namespace
}  // namespace ignav::workflow
