// The ProstateBRP communication test suite (June 2013) as a strict navigation client would run it
// against ignav's "brp2013" protocol revision (`--igtl-protocol brp2013`): its ten scenarios, each
// against a fresh ignav-server over real OpenIGTLink on loopback, the navigation side written with
// libOpenIGTLink (brp2013_client.hpp). Every message is checked in order, exactly: type, device
// name, STATUS code, CURRENT_STATUS's workphase (in its error name) and code 1, STRING text and
// encoding, echoes element for element; nothing else may come in between, nor on connect.
// Per-message budgets: an ACK (or echo) 1 s, a result 5 s, 10 s where the suite reads with its
// medium timeout. The sequences, and where ours differ from the suite: docs/OPENIGTLINK.md. DDS
// domains 200-210.
//
// Where the suite's own targets cannot be reached by this robot (the reference puts them at robot
// (0, 0, 0) with an identity calibration; our tips are 135-200 mm below the base), the CLB maps
// the suite's target onto a reachable point instead: identity rotation, a translation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include <Eigen/Core>

#include "brp2013_client.hpp"
#include "e2e/server_process.hpp"
#include "support/dmc_emulator.hpp"

namespace ignav::brp2013_test {
namespace {

using e2e::phaseIs;
using e2e::ServerProcess;
using e2e::stateText;
using nlohmann::json;
using namespace std::chrono_literals;

// Per-message budgets (notes §2.2 and §7), widened under AddressSanitizer.
constexpr int kSlow = e2e::kSanitized ? 3 : 1;
const Ms kAck{1000 * kSlow};      // an ACK_<id>: a command's STRING, a CLB's or TGT's echo
const Ms kResult{5000 * kSlow};   // a result, a CURRENT_STATUS, the next position while moving
const Ms kMedium{10000 * kSlow};  // where the suite reads with its medium timeout ([M])

// A tip position this robot reaches (robot frame, mm; as tests/igtl/brp_e2e_test.cpp uses).
const Eigen::Vector3d kReachableRobot_mm(-10, 15, -190);

// A TGT: identity rotation, the target's RAS position as translation.
Eigen::Matrix4d targetAt(const Eigen::Vector3d& ras_mm) {
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.topRightCorner<3, 1>() = ras_mm;
  return t;
}

// A CLB (RAS -> robot, rigid): identity rotation and the translation that puts the client's
// target at the reachable point, p_robot = p_ras + t.
Eigen::Matrix4d calibrationFor(const Eigen::Vector3d& target_ras_mm) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topRightCorner<3, 1>() = kReachableRobot_mm - target_ras_mm;
  return m;
}

Eigen::Vector3d translation(const Eigen::Matrix4d& m) {
  return m.topRightCorner<3, 1>();
}

// The suite's targets (notes §2.5): (0, 0, 0) in tests 1, 9 and 10, (20, 40, 50) in 6 and 7.
const Eigen::Vector3d kTargetRas(0, 0, 0);
const Eigen::Vector3d kTargetRasStop(20, 40, 50);

// The server's command line for the brp2013 revision, motion approval over OpenIGTLink allowed.
std::vector<std::string> brp2013(std::vector<std::string> args = {}) {
  args.insert(args.end(), {"--igtl-protocol", "brp2013", "--igtl-allow-approval"});
  return args;
}

// A navigation session: the suite's id counter (one for CMD, CLB and TGT) and its steps.
class Navigation {
 public:
  explicit Navigation(int port) : client_(port) {}
  StrictClient& client() { return client_; }

  // Connected, and nothing comes before the first command (no greeting).
  void connect() {
    ASSERT_TRUE(client_.connected());
    ASSERT_NO_FATAL_FAILURE(client_.expectNothing(500ms, "on connect, before any command"));
  }

  std::string nextId() { return fmt::format("{:04d}", ++id_); }
  // The suite's ids are literals: a step a test leaves out still uses its number.
  void skipId() { ++id_; }

  // STRING(CMD_<id>, phase), and its receipt STRING(ACK_<id>, phase) the very next message.
  void command(const std::string& phase) {
    const std::string id = nextId();
    client_.sendString("CMD_" + id, phase);
    ASSERT_NO_FATAL_FAILURE(client_.expectString("ACK_" + id, phase, kAck));
  }
  // A command answered with CURRENT_STATUS(phase) alone (PLANNING, CALIBRATION).
  void commandSilent(const std::string& phase) {
    ASSERT_NO_FATAL_FAILURE(command(phase));
    ASSERT_NO_FATAL_FAILURE(client_.expectCurrentStatus(phase, kResult));
  }
  // A command answered with CURRENT_STATUS(phase), then its result STATUS(phase, code).
  // With `error_name`, the result's error name is that (docs/OPENIGTLINK.md, "Error names").
  void commandAnswered(const std::string& phase, int code, Ms result_within = kResult,
                       const char* error_name = nullptr) {
    ASSERT_NO_FATAL_FAILURE(commandSilent(phase));
    Message m;
    ASSERT_NO_FATAL_FAILURE(client_.expectStatus(phase, code, result_within, &m));
    if (error_name) {
      EXPECT_EQ(m.error_name, error_name) << describe(m);
    }
  }

  // TRANSFORM(CLB_<id>, m): the echo, then STATUS(CALIBRATION, code), nothing else.
  void calibrate(const Eigen::Matrix4d& m, int code, const char* error_name = nullptr) {
    const std::string id = nextId();
    client_.sendTransform("CLB_" + id, m);
    ASSERT_NO_FATAL_FAILURE(client_.expectEcho(id, m, kAck));
    Message result;
    ASSERT_NO_FATAL_FAILURE(client_.expectStatus("CALIBRATION", code, kResult, &result));
    if (error_name) {
      EXPECT_EQ(result.error_name, error_name) << describe(result);
    }
  }
  // TRANSFORM(TGT_<id>, t) and its echo.
  void sendTarget(const Eigen::Matrix4d& t) {
    const std::string id = nextId();
    client_.sendTransform("TGT_" + id, t);
    ASSERT_NO_FATAL_FAILURE(client_.expectEcho(id, t, kAck));
  }
  // A reachable target: the echo, STATUS(TARGET, 1), TRANSFORM(TARGET) where the tip will be.
  void target(const Eigen::Matrix4d& t) {
    ASSERT_NO_FATAL_FAILURE(sendTarget(t));
    ASSERT_NO_FATAL_FAILURE(client_.expectStatus("TARGET", 1, kResult));
    Message reachable;
    ASSERT_NO_FATAL_FAILURE(client_.expectTransform("TARGET", kMedium, &reachable));
    EXPECT_LT((translation(reachable.matrix) - translation(t)).norm(), 0.5)
        << "TRANSFORM(TARGET) is the reachable tip pose in RAS: " << describe(reachable);
  }

  // START_UP, PLANNING, CALIBRATION with the CLB `m`, TARGETING: the suite's ids 0001-0005.
  void calibrated(const Eigen::Matrix4d& m) {
    ASSERT_NO_FATAL_FAILURE(commandAnswered("START_UP", 1));
    ASSERT_NO_FATAL_FAILURE(commandSilent("PLANNING"));
    ASSERT_NO_FATAL_FAILURE(commandSilent("CALIBRATION"));
    ASSERT_NO_FATAL_FAILURE(calibrate(m, 1));
    ASSERT_NO_FATAL_FAILURE(commandAnswered("TARGETING", 1));
  }
  // The suite's prefix up to the target (TGT_0006), calibrated so that it is reachable.
  void targeted(const Eigen::Vector3d& target_ras) {
    ASSERT_NO_FATAL_FAILURE(calibrated(calibrationFor(target_ras)));
    ASSERT_NO_FATAL_FAILURE(target(targetAt(target_ras)));
  }
  // MOVE_TO_TARGET: its ACK and CURRENT_STATUS(MOVE_TO_TARGET); the robot is released.
  void moveStarted() {
    ASSERT_NO_FATAL_FAILURE(command("MOVE_TO_TARGET"));
    ASSERT_NO_FATAL_FAILURE(client_.expectCurrentStatus("MOVE_TO_TARGET", kResult));
  }

  // While moving: only TRANSFORM(CURRENT_POSITION), each within 5 s of the one before, until
  // STATUS(MOVE_TO_TARGET, 1); then exactly one more TRANSFORM(CURRENT_POSITION), the tip at
  // rest on the target.
  void arrival(const Eigen::Vector3d& target_ras) {
    const auto deadline = Clock::now() + 120s;
    Message m;
    for (;;) {
      ASSERT_LT(Clock::now(), deadline) << "still moving after 120 s";
      ASSERT_NO_FATAL_FAILURE(
          client_.receive(kResult, "TRANSFORM(CURRENT_POSITION) or STATUS(MOVE_TO_TARGET, 1)", &m));
      if (m.type != "TRANSFORM") break;
      ASSERT_EQ(m.device, "CURRENT_POSITION")
          << "only CURRENT_POSITION while moving: " << describe(m);
    }
    ASSERT_EQ(m.type, "STATUS") << describe(m);
    ASSERT_EQ(m.device, "MOVE_TO_TARGET") << describe(m);
    ASSERT_EQ(m.code, 1) << describe(m);
    Message rest;
    ASSERT_NO_FATAL_FAILURE(client_.expectTransform("CURRENT_POSITION", kMedium, &rest));
    EXPECT_LT((translation(rest.matrix) - target_ras).norm(), 0.5)
        << "the tip at rest, in RAS: " << describe(rest);
    ASSERT_NO_FATAL_FAILURE(
        client_.expectNothing(500ms, "after the one CURRENT_POSITION that follows the arrival"));
  }

  // While moving, after the `after_positions`-th CURRENT_POSITION: STRING(CMD_<id>, phase) (STOP
  // or EMERGENCY). Then its ACK before any STATUS (within 1 s of the command), and then, in
  // either order, CURRENT_STATUS(phase) (code 1) and STATUS(phase, 1), within 5 s of the ACK;
  // CURRENT_POSITIONs may come in between, nothing else.
  void interrupt(const std::string& phase, int after_positions = 6) {
    const auto deadline = Clock::now() + 120s;
    int positions = 0;
    bool sent = false, acked = false, current = false, result = false;
    std::string id;
    Clock::time_point sent_at, acked_at;
    while (!(current && result)) {
      ASSERT_LT(Clock::now(), deadline)
          << "still moving after 120 s, " << positions << " positions";
      Ms within = kResult;
      std::string expected = "TRANSFORM(CURRENT_POSITION)";
      if (sent && !acked) {
        within = std::chrono::duration_cast<Ms>(sent_at + kAck - Clock::now());
        expected = "STRING(ACK_" + id + ", " + phase + ") within " + std::to_string(kAck.count()) +
                   " ms of the command";
      } else if (acked) {
        within = std::chrono::duration_cast<Ms>(acked_at + kResult - Clock::now());
        expected = "CURRENT_STATUS(" + phase + ") and STATUS(" + phase + ", 1) within " +
                   std::to_string(kResult.count()) + " ms of the ACK";
      }
      ASSERT_GT(within.count(), 0) << "nothing but positions came; expected " << expected;
      Message m;
      ASSERT_NO_FATAL_FAILURE(client_.receive(within, expected, &m));
      if (m.type == "TRANSFORM") {
        ASSERT_EQ(m.device, "CURRENT_POSITION")
            << "only CURRENT_POSITION while moving: " << describe(m);
        if (!sent && ++positions >= after_positions) {
          id = nextId();
          client_.sendString("CMD_" + id, phase);
          sent = true;
          sent_at = Clock::now();
        }
        continue;
      }
      ASSERT_TRUE(sent) << "only CURRENT_POSITION may come while moving, and the move must last "
                        << after_positions << " of them (the " << phase << " is sent then); got "
                        << describe(m) << " after " << positions;
      if (m.type == "STRING") {
        ASSERT_FALSE(acked) << "a second STRING: " << describe(m);
        ASSERT_EQ(m.device, "ACK_" + id) << describe(m);
        ASSERT_EQ(m.text, phase) << describe(m);
        EXPECT_EQ(m.encoding, 3) << describe(m);
        acked = true;
        acked_at = Clock::now();
        continue;
      }
      ASSERT_EQ(m.type, "STATUS") << "unexpected: " << describe(m);
      ASSERT_TRUE(acked) << "a STATUS before the ACK of " << phase << ": " << describe(m);
      if (m.device == "CURRENT_STATUS") {
        ASSERT_FALSE(current) << "a second CURRENT_STATUS: " << describe(m);
        ASSERT_EQ(m.code, 1) << describe(m);
        ASSERT_EQ(m.error_name, phase) << describe(m);
        current = true;
      } else {
        ASSERT_EQ(m.device, phase) << "no STATUS but CURRENT_STATUS and " << phase
                                   << "'s own after the ACK: " << describe(m);
        ASSERT_FALSE(result) << "a second result: " << describe(m);
        ASSERT_EQ(m.code, 1) << describe(m);
        result = true;
      }
    }
  }

  // For `duration`: only TRANSFORM(CURRENT_POSITION) (the robot coming to rest).
  void onlyPositions(Ms duration) {
    client_.drain(
        duration,
        [](const Message& m) { return m.type == "TRANSFORM" && m.device == "CURRENT_POSITION"; },
        "TRANSFORM(CURRENT_POSITION)");
  }

 private:
  StrictClient client_;
  int id_ = 0;
};

// Polls a DDS client until `done` holds; false after `timeout`.
bool waitState(protocol::Client& c, const std::function<bool(const json&)>& done, Ms timeout) {
  try {
    c.waitFor(done, timeout);
    return true;
  } catch (const protocol::Timeout&) {
    return false;
  }
}

// The motion topic's fields that change when anything moves or is released to move.
json motionSnapshot(protocol::Client& c) {
  c.poll();
  const json& s = c.state();
  if (!s.contains("motion") || !s["motion"].is_object()) return json();
  const json& m = s["motion"];
  json out;
  for (const char* key : {"steps", "goal_steps", "plan_id", "move_count", "move_index"}) {
    out[key] = m.contains(key) ? m[key] : json();
  }
  return out;
}

// After a halt: the workflow in `phase`, the motion state `motion` ("" for any but moving), and
// the motors staying where they are.
void expectAtRest(protocol::Client& viewer, const std::string& phase, const std::string& motion) {
  const bool settled = waitState(
      viewer,
      [&](const json& s) {
        const std::string state = stateText(s, "motion", "state");
        return phaseIs(s, phase.c_str()) && !state.empty() &&
               (motion.empty() ? state != "moving" : state == motion);
      },
      10s);
  EXPECT_TRUE(settled) << "expected phase " << phase << " and motion state "
                       << (motion.empty() ? "other than moving" : motion) << "; workflow "
                       << (viewer.state().contains("workflow") ? viewer.state()["workflow"].dump()
                                                               : "none")
                       << ", motion state \"" << stateText(viewer.state(), "motion", "state")
                       << "\"";
  const json before = motionSnapshot(viewer);
  std::this_thread::sleep_for(500ms);
  EXPECT_EQ(motionSnapshot(viewer), before) << "the robot is still moving";
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// Test 1 (notes §4): the whole procedure, then MANUAL, STOP from manual and EMERGENCY.
TEST(Brp2013, NormalOperation) {
  ServerProcess server(200, brp2013({"--controller-speed", "40000"}));
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  ASSERT_NO_FATAL_FAILURE(nav.targeted(kTargetRas));  // CMD_0001 ... CLB_0004 ... TGT_0006
  ASSERT_NO_FATAL_FAILURE(nav.moveStarted());         // CMD_0007
  ASSERT_NO_FATAL_FAILURE(nav.arrival(kTargetRas));
  ASSERT_NO_FATAL_FAILURE(nav.commandAnswered("MANUAL", 1));     // CMD_0008
  ASSERT_NO_FATAL_FAILURE(nav.commandAnswered("STOP", 1));       // CMD_0009, from manual
  ASSERT_NO_FATAL_FAILURE(nav.commandAnswered("EMERGENCY", 1));  // CMD_0010
  ASSERT_NO_FATAL_FAILURE(nav.client().expectNothing(1s, "after the emergency stop's result"));
}

// Test 2: the controller cannot be reached. START_UP answers "not ready" (13).
TEST(Brp2013, StartUpError) {
  ServerProcess server(
      201,
      brp2013({"--controller", "galil:127.0.0.1:" + std::to_string(test::closedLoopbackPort())}));
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  ASSERT_NO_FATAL_FAILURE(nav.commandAnswered("START_UP", 13, kResult, "no_controller"));
  ASSERT_NO_FATAL_FAILURE(nav.client().expectNothing(1s, "after STATUS(START_UP, 13)"));
  EXPECT_TRUE(server.alive());
}

// Test 3: a CLB of sixteen 1.0s is no rigid transform: configuration error (10).
TEST(Brp2013, CalibrationError) {
  ServerProcess server(202, brp2013());
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  ASSERT_NO_FATAL_FAILURE(nav.commandAnswered("START_UP", 1));
  ASSERT_NO_FATAL_FAILURE(nav.commandSilent("PLANNING"));
  ASSERT_NO_FATAL_FAILURE(nav.commandSilent("CALIBRATION"));
  ASSERT_NO_FATAL_FAILURE(
      nav.calibrate(Eigen::Matrix4d::Ones(), 10, "not_similarity"));  // CLB_0004
  ASSERT_NO_FATAL_FAILURE(nav.client().expectNothing(1s, "after STATUS(CALIBRATION, 10)"));
}

// Test 4: TARGETING without a CLB. CURRENT_STATUS names the requested workphase all the same;
// the result says "not ready" (13).
TEST(Brp2013, TargetingWithoutCalibration) {
  ServerProcess server(203, brp2013());
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  ASSERT_NO_FATAL_FAILURE(nav.commandAnswered("START_UP", 1));
  ASSERT_NO_FATAL_FAILURE(nav.commandSilent("PLANNING"));
  ASSERT_NO_FATAL_FAILURE(nav.commandSilent("CALIBRATION"));
  nav.skipId();  // no CLB_0004
  ASSERT_NO_FATAL_FAILURE(
      nav.commandAnswered("TARGETING", 13, kResult, "not_registered"));  // CMD_0005
  ASSERT_NO_FATAL_FAILURE(nav.client().expectNothing(1s, "after STATUS(TARGETING, 13)"));
}

// Test 5: a target 5 m up in S. Configuration error (10), nothing after it, and the reason named
// for what it is.
TEST(Brp2013, OutOfRangeTarget) {
  ServerProcess server(204, brp2013());
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  ASSERT_NO_FATAL_FAILURE(nav.calibrated(calibrationFor(kTargetRas)));
  ASSERT_NO_FATAL_FAILURE(nav.sendTarget(targetAt({0, 0, 5000})));  // TGT_0006
  Message refused;
  ASSERT_NO_FATAL_FAILURE(nav.client().expectStatus("TARGET", 10, kResult, &refused));
  EXPECT_EQ(refused.error_name, "unreachable") << describe(refused);
  EXPECT_TRUE(refused.status_ascii) << describe(refused);
  const std::string why = lower(refused.status_string);
  EXPECT_EQ(why.find("minimum radius"), std::string::npos)
      << "the target is far above the reach, not near the axis: " << describe(refused);
  const bool named =
      why.find("shallow") != std::string::npos || why.find("above") != std::string::npos ||
      why.find("too far") != std::string::npos || why.find("beyond") != std::string::npos;
  EXPECT_TRUE(named) << "the reason (too far / above the reach) must be named: "
                     << describe(refused);
  ASSERT_NO_FATAL_FAILURE(nav.client().expectNothing(1s, "after STATUS(TARGET, 10)"));
}

// Tests 6 and 7: STOP (EMERGENCY) after the 6th position. Its ACK before any STATUS, then
// CURRENT_STATUS(STOP) (code 1) and STATUS(STOP, 1); no report on the interrupted move, ever; the
// robot at rest in `phase`.
void haltDuringOperation(int domain, const std::string& halt, const char* phase,
                         const char* motion) {
  ServerProcess server(domain, brp2013({"--controller-speed", "2000"}));  // a move seconds long
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  auto viewer = server.client("viewer");
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  ASSERT_NO_FATAL_FAILURE(nav.targeted(kTargetRasStop));
  ASSERT_NO_FATAL_FAILURE(nav.moveStarted());       // CMD_0007
  ASSERT_NO_FATAL_FAILURE(nav.interrupt(halt, 6));  // CMD_0008
  ASSERT_NO_FATAL_FAILURE(nav.onlyPositions(1500ms));
  expectAtRest(*viewer, phase, motion);
}

TEST(Brp2013, StopDuringOperation) {
  haltDuringOperation(205, "STOP", "stopped", "idle");
}

TEST(Brp2013, EmergencyStopDuringOperation) {
  haltDuringOperation(206, "EMERGENCY", "emergency", "");
}

// Test 8: MOVE_TO_TARGET with no target: "not ready" (13), and nothing moves.
TEST(Brp2013, MoveToWithoutTarget) {
  ServerProcess server(207, brp2013({"--controller-speed", "40000"}));
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  ASSERT_NO_FATAL_FAILURE(nav.calibrated(calibrationFor(kTargetRas)));
  nav.skipId();  // no TGT_0006
  ASSERT_NO_FATAL_FAILURE(
      nav.commandAnswered("MOVE_TO_TARGET", 13, kMedium, "empty_plan"));  // CMD_0007
  ASSERT_NO_FATAL_FAILURE(
      nav.client().expectNothing(1s, "after STATUS(MOVE_TO_TARGET, 13) (no CURRENT_POSITION)"));
}

// Test 9: under manual control a MOVE_TO_TARGET, with a reachable target planned, is refused
// ("not ready", 13), and nothing moves.
TEST(Brp2013, AccidentalCommandDuringManualMode) {
  ServerProcess server(208, brp2013({"--controller-speed", "40000"}));
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  auto viewer = server.client("viewer");
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  ASSERT_NO_FATAL_FAILURE(nav.targeted(kTargetRas));  // up to TGT_0006
  nav.skipId();                                       // the suite moves with CMD_0007; not here
  ASSERT_NO_FATAL_FAILURE(nav.commandAnswered("MANUAL", 1));  // CMD_0008
  ASSERT_TRUE(waitState(
      *viewer, [](const json& s) { return s.contains("motion"); }, 10s));
  const json before = motionSnapshot(*viewer);
  ASSERT_NO_FATAL_FAILURE(
      nav.commandAnswered("MOVE_TO_TARGET", 13, kMedium, "wrong_phase"));  // CMD_0009
  ASSERT_NO_FATAL_FAILURE(
      nav.client().expectNothing(1s, "after STATUS(MOVE_TO_TARGET, 13) (no CURRENT_POSITION)"));
  EXPECT_EQ(motionSnapshot(*viewer), before) << "something moved, or was released to move";
  EXPECT_NE(stateText(viewer->state(), "motion", "state"), "moving");
}

// Test 10: the controller dies mid-move. Positions, then STATUS(MOVE_TO_TARGET, 18) (hardware
// failure); never an arrival.
TEST(Brp2013, HardwareErrorDuringOperation) {
  test::Emulator dmc;
  ServerProcess server(209,
                       brp2013({"--controller", "galil:127.0.0.1:" + std::to_string(dmc.port()),
                                "--controller-speed", "2000"}));
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  ASSERT_NO_FATAL_FAILURE(nav.targeted(kTargetRas));
  ASSERT_NO_FATAL_FAILURE(nav.moveStarted());  // CMD_0007
  const auto deadline = Clock::now() + 120s;
  int positions = 0;
  bool killed = false;
  Message m;
  for (;;) {
    ASSERT_LT(Clock::now(), deadline) << "no result 120 s after the move started";
    ASSERT_NO_FATAL_FAILURE(nav.client().receive(
        kResult, "TRANSFORM(CURRENT_POSITION) or STATUS(MOVE_TO_TARGET, 18)", &m));
    if (m.type != "TRANSFORM") break;
    ASSERT_EQ(m.device, "CURRENT_POSITION")
        << "only CURRENT_POSITION while moving: " << describe(m);
    if (!killed && ++positions >= 2) {
      dmc.kill();  // the controller vanishes mid-move
      killed = true;
    }
  }
  ASSERT_TRUE(killed) << "the move must last 2 positions (the controller dies then); got "
                      << describe(m) << " after " << positions;
  ASSERT_EQ(m.type, "STATUS") << describe(m);
  ASSERT_EQ(m.device, "MOVE_TO_TARGET") << describe(m);
  ASSERT_EQ(m.code, 18) << "hardware failure expected: " << describe(m);
  EXPECT_EQ(m.error_name, "fault") << describe(m);
  ASSERT_NO_FATAL_FAILURE(nav.onlyPositions(1500ms));
  EXPECT_TRUE(server.alive());
}

// Beyond the ten: whatever a command's outcome (accepted, refused, moving or not), its ACK comes
// before any other message of it. Only that is checked here.
TEST(Brp2013, EveryCommandIsAcknowledgedFirst) {
  ServerProcess server(210, brp2013({"--controller-speed", "40000"}));
  ASSERT_GT(server.igtlPort(), 0) << "the server did not start";
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.connect());
  // Until the server has been quiet for a second: whatever answers and positions there are.
  auto settle = [&] {
    const auto until = Clock::now() + 60s;
    while (Clock::now() < until && nav.client().next(1s)) {
    }
  };
  auto command = [&](const std::string& phase) {
    SCOPED_TRACE(phase);
    ASSERT_NO_FATAL_FAILURE(nav.command(phase));
    settle();
  };
  auto transform = [&](const std::string& prefix, const Eigen::Matrix4d& m) {
    SCOPED_TRACE(prefix);
    const std::string id = nav.nextId();
    nav.client().sendTransform(prefix + "_" + id, m);
    ASSERT_NO_FATAL_FAILURE(nav.client().expectEcho(id, m, kAck));
    settle();
  };
  ASSERT_NO_FATAL_FAILURE(command("START_UP"));
  ASSERT_NO_FATAL_FAILURE(command("TARGETING"));       // not calibrated
  ASSERT_NO_FATAL_FAILURE(command("MOVE_TO_TARGET"));  // no target
  ASSERT_NO_FATAL_FAILURE(command("PLANNING"));
  ASSERT_NO_FATAL_FAILURE(command("CALIBRATION"));
  ASSERT_NO_FATAL_FAILURE(transform("CLB", Eigen::Matrix4d::Ones()));  // refused
  ASSERT_NO_FATAL_FAILURE(transform("CLB", calibrationFor(kTargetRas)));
  ASSERT_NO_FATAL_FAILURE(command("TARGETING"));
  ASSERT_NO_FATAL_FAILURE(command("MOVE_TO_TARGET"));                 // no target yet
  ASSERT_NO_FATAL_FAILURE(transform("TGT", targetAt({0, 0, 5000})));  // out of range
  ASSERT_NO_FATAL_FAILURE(transform("TGT", targetAt(kTargetRas)));
  ASSERT_NO_FATAL_FAILURE(command("MOVE_TO_TARGET"));  // moves, and arrives
  ASSERT_NO_FATAL_FAILURE(command("MANUAL"));
  ASSERT_NO_FATAL_FAILURE(command("MOVE_TO_TARGET"));  // refused in manual
  ASSERT_NO_FATAL_FAILURE(command("STOP"));
  ASSERT_NO_FATAL_FAILURE(command("START_UP"));
  ASSERT_NO_FATAL_FAILURE(command("EMERGENCY"));
  ASSERT_NO_FATAL_FAILURE(command("START_UP"));  // in an emergency
  ASSERT_NO_FATAL_FAILURE(command("EMERGENCY"));
}

}  // namespace
}  // namespace ignav::brp2013_test
