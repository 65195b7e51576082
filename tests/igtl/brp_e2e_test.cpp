// The BRP communication test suite's ten scenarios (ProstateBRP's OpenIGTLink workphase
// protocol), against a real ignav-server over real OpenIGTLink on loopback, the navigation side
// written with libOpenIGTLink. Each scenario checks the exact messages, in order; echoes are
// compared with an independently held copy of what was sent. DDS domains 160-176.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <thread>

#include <fmt/format.h>

#include <Eigen/Geometry>

#include "brp_client.hpp"
#include "e2e/server_process.hpp"
#include "support/dmc_emulator.hpp"

namespace ignav::brp_test {
namespace {

using e2e::phaseIs;
using e2e::ServerProcess;
using e2e::stateCount;
using e2e::stateText;
using nlohmann::json;
using namespace std::chrono_literals;

// Slicer's calibration: RAS -> robot, a 30° turn about S and a shift (as a Z-frame would give).
Eigen::Matrix4d calibration() {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() =
      Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  m.topRightCorner<3, 1>() = Eigen::Vector3d(12.5, -20.0, -40.0);
  return m;
}

// What the wire carries: float32 elements.
Eigen::Matrix4d asSent(const Eigen::Matrix4d& m) {
  return m.cast<float>().cast<double>();
}

// A target the robot reaches (robot frame; as the fault tests use), and one above the skin.
const Eigen::Vector3d kReachableRobot_mm(-10, 15, -190);
const Eigen::Vector3d kUnreachableRobot_mm(0, 0, 50);

// Where Slicer would click for a robot-frame point: p_ras = M^-1 p_robot.
Eigen::Matrix4d targetRas(const Eigen::Vector3d& robot_mm) {
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.topRightCorner<3, 1>() = (asSent(calibration()).inverse() * robot_mm.homogeneous()).head<3>();
  return t;
}

// A navigation-side session: every call checks the exact messages that come back.
class Navigation {
 public:
  explicit Navigation(int port) : client_(port) {
    EXPECT_TRUE(client_.connected());
    client_.ignore({"CURRENT_POSITION", "NeedleTipToImage"});
  }
  BrpClient& client() { return client_; }

  Received next(const char* what) {
    auto r = client_.next(10s);
    EXPECT_TRUE(r.has_value()) << "nothing came; expected " << what;
    return r.value_or(Received{});
  }
  void expectStatus(const char* device, int code, const char* error_name = nullptr,
                    const char* status_string = nullptr, std::chrono::seconds wait = 10s) {
    auto r = client_.next(wait);
    ASSERT_TRUE(r.has_value()) << "nothing came; expected STATUS(" << device << ")";
    EXPECT_EQ(r->type, "STATUS") << *r;
    EXPECT_EQ(r->device, device) << *r;
    EXPECT_EQ(r->code, code) << *r << " " << r->error_name;
    if (error_name) {
      EXPECT_EQ(r->error_name, error_name) << *r;
    }
    if (status_string) {
      EXPECT_EQ(r->status_string, status_string) << *r;
    }
  }
  void expectCurrentStatus(const char* phase, int code = 1) {
    expectStatus("CURRENT_STATUS", code, nullptr, phase);
  }
  // STRING(CMD_<id>, phase) and its receipt STRING(ACK_<id>, phase).
  void command(const std::string& phase) {
    const std::string id = next_id();
    client_.sendString("CMD_" + id, phase);
    auto ack = next("the ACK");
    EXPECT_EQ(ack.type, "STRING") << ack;
    EXPECT_EQ(ack.device, "ACK_" + id) << ack;
    EXPECT_EQ(ack.text, phase) << ack;
  }
  // A command answered with the workphase and its result.
  void commandExpect(const std::string& phase, const char* current, int current_code, int code,
                     const char* error_name = nullptr) {
    command(phase);
    ASSERT_NO_FATAL_FAILURE(expectCurrentStatus(current, current_code));
    ASSERT_NO_FATAL_FAILURE(expectStatus(phase.c_str(), code, error_name));
  }
  // TRANSFORM(<prefix>_<id>) and its echo TRANSFORM(ACK_<id>), equal to what was sent.
  void transform(const std::string& prefix, const Eigen::Matrix4d& m) {
    const std::string id = next_id();
    client_.sendTransform(prefix + "_" + id, m);
    auto ack = next("the echo");
    EXPECT_EQ(ack.type, "TRANSFORM") << ack;
    EXPECT_EQ(ack.device, "ACK_" + id) << ack;
    // Bit for bit: the echo carries the received float32 elements unchanged.
    EXPECT_EQ((ack.matrix - asSent(m)).cwiseAbs().maxCoeff(), 0.0) << ack.matrix;
  }
  Received expectTransform(const char* device) {
    auto r = next(device);
    EXPECT_EQ(r.type, "TRANSFORM") << r;
    EXPECT_EQ(r.device, device) << r;
    return r;
  }
  // START_UP, PLANNING, CALIBRATION with Slicer's matrix, TARGETING.
  void calibrated() {
    ASSERT_NO_FATAL_FAILURE(commandExpect("START_UP", "START_UP", 1, 1));
    ASSERT_NO_FATAL_FAILURE(commandExpect("PLANNING", "PLANNING", 1, 1));
    ASSERT_NO_FATAL_FAILURE(commandExpect("CALIBRATION", "CALIBRATION", 1, 1));
    ASSERT_NO_FATAL_FAILURE(transform("CLB", calibration()));
    ASSERT_NO_FATAL_FAILURE(expectStatus("CALIBRATION", 1));
    const auto reg = expectTransform("ImageToRobot");
    EXPECT_LT((reg.matrix - calibration()).cwiseAbs().maxCoeff(), 1e-5) << reg.matrix;
    ASSERT_NO_FATAL_FAILURE(commandExpect("TARGETING", "TARGETING", 1, 1));
  }
  // A reachable target: its echo, STATUS(TARGET, OK) and where the robot will put the tip.
  void target() {
    const Eigen::Matrix4d t = targetRas(kReachableRobot_mm);
    ASSERT_NO_FATAL_FAILURE(transform("TGT", t));
    ASSERT_NO_FATAL_FAILURE(expectStatus("TARGET", 1));
    const auto reachable = expectTransform("REACHABLE_TARGET");
    // The exact inverse kinematics: the reachable point is the target, to the micrometre.
    EXPECT_LT((reachable.matrix.topRightCorner<3, 1>() - t.topRightCorner<3, 1>()).norm(), 1e-3);
  }
  // MOVE_TO_TARGET released over OpenIGTLink (the server allows it): moving.
  void moveStarted() {
    command("MOVE_TO_TARGET");
    ASSERT_NO_FATAL_FAILURE(expectCurrentStatus("MOVE_TO_TARGET"));
  }
  // Waits until the tip has been reported moving.
  void waitForMotion() {
    const auto until = std::chrono::steady_clock::now() + 10s;
    while (std::chrono::steady_clock::now() < until) {
      for (const auto& r : client_.takeStreamed()) {
        if (r.device == "CURRENT_POSITION") return;
      }
      std::this_thread::sleep_for(10ms);
      (void)client_.next(10ms);  // keeps reading; nothing else is expected meanwhile
    }
    ADD_FAILURE() << "no CURRENT_POSITION while moving";
  }
  void expectOpening() { expectCurrentStatus("START_UP"); }
  // From the greeting to the robot's arrival at the reachable target.
  void arrived() {
    ASSERT_NO_FATAL_FAILURE(expectOpening());
    ASSERT_NO_FATAL_FAILURE(calibrated());
    ASSERT_NO_FATAL_FAILURE(target());
    ASSERT_NO_FATAL_FAILURE(moveStarted());
    ASSERT_NO_FATAL_FAILURE(expectStatus("MOVE_TO_TARGET", 1, nullptr, "arrived at target 1", 30s));
  }
  // From the greeting to a robot on its way to the reachable target.
  void underWay() {
    ASSERT_NO_FATAL_FAILURE(expectOpening());
    ASSERT_NO_FATAL_FAILURE(calibrated());
    ASSERT_NO_FATAL_FAILURE(target());
    ASSERT_NO_FATAL_FAILURE(moveStarted());
    ASSERT_NO_FATAL_FAILURE(waitForMotion());
  }

 private:
  std::string next_id() { return fmt::format("{:04d}", ++id_); }
  BrpClient client_;
  int id_ = 0;
};

std::vector<std::string> withApproval(std::vector<std::string> args = {}) {
  args.push_back("--igtl-allow-approval");
  return args;
}

TEST(BrpE2E, NormalOperation) {
  ServerProcess server(160, withApproval({"--controller-speed", "40000"}));
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.arrived());
  // Where it came to rest follows the result (the 2013 reference client waits for it too).
  nav.client().ignore({"NeedleTipToImage"});
  const auto rest = nav.expectTransform("CURRENT_POSITION");
  nav.client().ignore({"CURRENT_POSITION", "NeedleTipToImage"});
  // The tip was streamed on its way, and it came to rest on the target.
  const auto streamed = nav.client().takeStreamed();
  std::vector<Received> positions, tips;
  for (const auto& r : streamed)
    (r.device == "CURRENT_POSITION" ? positions : tips).push_back(r);
  ASSERT_GE(positions.size(), 2u);
  EXPECT_EQ(positions.size(), tips.size());
  const Eigen::Vector3d target = targetRas(kReachableRobot_mm).topRightCorner<3, 1>();
  // Whole motor steps: the tip lands within the transmission's resolution of the target.
  EXPECT_LT((positions.back().matrix.topRightCorner<3, 1>() - target).norm(), 0.05);
  EXPECT_LT((rest.matrix.topRightCorner<3, 1>() - target).norm(), 0.05);
  // At rest, the query answers with the same position.
  nav.client().ignore({});
  nav.client().sendGetTransform("CURRENT_POSITION");
  const auto answered = nav.expectTransform("CURRENT_POSITION");
  EXPECT_EQ(answered.matrix, positions.back().matrix);
  EXPECT_EQ(answered.matrix, rest.matrix);
  nav.client().sendGetStatus("CURRENT_STATUS");
  ASSERT_NO_FATAL_FAILURE(nav.expectCurrentStatus("MOVE_TO_TARGET"));
  // The DDS view agrees: the target is reached, and the approval came from OpenIGTLink, loudly.
  auto viewer = server.client("viewer");
  viewer->waitFor([](const json& s) { return phaseIs(s, "at_target"); }, 10s);
  EXPECT_NE(stateText(viewer->state(), "workflow", "safety_notice").find("OpenIGTLink"),
            std::string::npos);
}

TEST(BrpE2E, AccidentalCommandInManualMode) {
  ServerProcess server(161, withApproval());
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.expectOpening());
  ASSERT_NO_FATAL_FAILURE(nav.calibrated());
  ASSERT_NO_FATAL_FAILURE(nav.target());
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("MANUAL", "MANUAL", 14, 1));
  // Commands meant for computer control are refused with "manual mode"; nothing moves.
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("TARGETING", "MANUAL", 14, 14, "wrong_phase"));
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("MOVE_TO_TARGET", "MANUAL", 14, 14, "wrong_phase"));
  // A stop button always stops (issue 25): taken, the controller halted again, manual stays.
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("STOP", "MANUAL", 14, 1));
  auto viewer = server.client("viewer");
  // Each state topic arrives on its own: wait for the approval state too, then judge it.
  viewer->waitFor(
      [](const json& s) {
        return phaseIs(s, "manual") && !stateText(s, "approval", "status").empty();
      },
      10s);
  EXPECT_EQ(stateText(viewer->state(), "approval", "status"), "none");
  // START_UP takes the robot back; the plan is where it was.
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("START_UP", "START_UP", 1, 1));
  viewer->waitFor([](const json& s) { return phaseIs(s, "planning"); }, 10s);
}

TEST(BrpE2E, CalibrationError) {
  ServerProcess server(162);
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.expectOpening());
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("START_UP", "START_UP", 1, 1));
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("CALIBRATION", "CALIBRATION", 1, 1));
  Eigen::Matrix4d sheared = calibration();
  sheared(0, 1) += 0.2;
  ASSERT_NO_FATAL_FAILURE(nav.transform("CLB", sheared));
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("CALIBRATION", 10, "not_similarity"));
  Eigen::Matrix4d mirrored = calibration();
  mirrored.row(2) *= -1.0;
  ASSERT_NO_FATAL_FAILURE(nav.transform("CLB", mirrored));
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("CALIBRATION", 10, "mirror"));
  // Nothing was registered.
  nav.client().sendGetTransform("ImageToRobot");
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("ImageToRobot", 13, "not_registered"));
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("TARGETING", "CALIBRATION", 1, 13, "not_registered"));
}

TEST(BrpE2E, EmergencyStopDuringOperation) {
  ServerProcess server(163, withApproval({"--controller-speed", "2000"}));
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.underWay());
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("EMERGENCY", "EMERGENCY", 3, 1));
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("MOVE_TO_TARGET", 3, "emergency"));
  auto viewer = server.client("viewer");
  viewer->waitFor([](const json& s) { return phaseIs(s, "emergency"); }, 10s);
  // Only an operator over DDS resets an emergency; OpenIGTLink commands meet "panic".
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("START_UP", "EMERGENCY", 3, 3, "wrong_phase"));
}

TEST(BrpE2E, HardwareErrorDuringOperation) {
  test::Emulator dmc;
  ServerProcess server(
      164, withApproval({"--controller", "galil:127.0.0.1:" + std::to_string(dmc.port()),
                         "--controller-speed", "2000"}));
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.underWay());
  dmc.kill();  // the controller vanishes mid-move
  ASSERT_NO_FATAL_FAILURE(nav.expectCurrentStatus("MOVE_TO_TARGET", 18));
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("MOVE_TO_TARGET", 18, "fault"));
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("MOVE_TO_TARGET", "MOVE_TO_TARGET", 18, 18));
  EXPECT_TRUE(server.alive());
}

TEST(BrpE2E, MoveWithoutTarget) {
  ServerProcess server(165, withApproval());
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.expectOpening());
  ASSERT_NO_FATAL_FAILURE(nav.calibrated());
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("MOVE_TO_TARGET", "TARGETING", 1, 13, "empty_plan"));
  auto viewer = server.client("viewer");
  viewer->waitFor([](const json& s) { return phaseIs(s, "planning"); }, 10s);
}

TEST(BrpE2E, OutOfRangeTarget) {
  ServerProcess server(166, withApproval());
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.expectOpening());
  ASSERT_NO_FATAL_FAILURE(nav.calibrated());
  ASSERT_NO_FATAL_FAILURE(nav.transform("TGT", targetRas(kUnreachableRobot_mm)));
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("TARGET", 10, "unreachable"));
  // It left the plan: moving now has no target; the reachable one is then accepted.
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("MOVE_TO_TARGET", "TARGETING", 1, 13, "empty_plan"));
  ASSERT_NO_FATAL_FAILURE(nav.target());
}

TEST(BrpE2E, StartUpError) {
  const int closed_port = test::closedLoopbackPort();
  ServerProcess server(167, {"--controller", "galil:127.0.0.1:" + std::to_string(closed_port)});
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.expectOpening());
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("START_UP", "START_UP", 1, 18, "no_controller"));
  EXPECT_TRUE(server.alive());
}

TEST(BrpE2E, StopDuringOperation) {
  ServerProcess server(168, withApproval({"--controller-speed", "2000"}));
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.underWay());
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("STOP", "STOP", 1, 1));
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("MOVE_TO_TARGET", 13, "stopped"));
  // Moving on again once the motors have come to rest: the rest of the way to the target.
  std::this_thread::sleep_for(1s);
  ASSERT_NO_FATAL_FAILURE(nav.moveStarted());
  ASSERT_NO_FATAL_FAILURE(
      nav.expectStatus("MOVE_TO_TARGET", 1, nullptr, "arrived at target 1", 60s));
}

TEST(BrpE2E, TargetingWithoutCalibration) {
  ServerProcess server(169, withApproval());
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.expectOpening());
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("START_UP", "START_UP", 1, 1));
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("TARGETING", "START_UP", 1, 13, "not_registered"));
  ASSERT_NO_FATAL_FAILURE(nav.transform("TGT", targetRas(kReachableRobot_mm)));
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("TARGET", 13, "wrong_phase"));
}

// Beyond the ten: what a site running Slicer beside DDS clients meets.

// Motion approval over OpenIGTLink is off by default: MOVE_TO_TARGET waits for an approver over
// DDS, and every connected Slicer hears the workphases and the arrival.
TEST(BrpE2E, WithoutApprovalRightsAMoveWaitsForADdsApprover) {
  ServerProcess server(170, {"--controller-speed", "40000"});
  Navigation watcher(server.igtlPort());  // a second Slicer, only listening
  ASSERT_NO_FATAL_FAILURE(watcher.expectOpening());
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.expectOpening());
  ASSERT_NO_FATAL_FAILURE(nav.calibrated());
  ASSERT_NO_FATAL_FAILURE(nav.target());
  nav.command("MOVE_TO_TARGET");
  ASSERT_NO_FATAL_FAILURE(nav.expectCurrentStatus("MOVE_TO_TARGET"));
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("MOVE_TO_TARGET", 13, "awaiting_approval"));
  auto op = server.client("operator");
  op->waitFor([](const json& s) { return stateText(s, "approval", "status") == "pending"; }, 10s);
  EXPECT_EQ(stateText(op->state(), "workflow", "phase"), "plan_locked");  // nothing moved
  EXPECT_EQ(stateText(op->state(), "workflow", "safety_notice"), "");
  // A DDS client cannot borrow the bridge's name.
  auto impostor = server.client("openigtlink");
  const json& a = op->state()["approval"];
  const auto refused =
      impostor->approve(a["plan_id"].get<std::uint64_t>(), a["digest"].get<std::string>());
  EXPECT_EQ(refused.error_code, "not_permitted") << refused.message;
  const auto approved =
      op->approve(a["plan_id"].get<std::uint64_t>(), a["digest"].get<std::string>());
  ASSERT_TRUE(approved.accepted) << approved.message;
  ASSERT_NO_FATAL_FAILURE(
      nav.expectStatus("MOVE_TO_TARGET", 1, nullptr, "arrived at target 1", 30s));
  // The listener heard every workphase change, the registration and the arrival, in order.
  std::vector<std::string> heard;
  while (auto r = watcher.client().next(500ms)) {
    heard.push_back(r->device + (r->type == "STATUS" ? ":" + r->status_string : ""));
  }
  const std::vector<std::string> expected = {"CURRENT_STATUS:PLANNING",
                                             "CURRENT_STATUS:CALIBRATION",
                                             "ImageToRobot",
                                             "CURRENT_STATUS:TARGETING",
                                             "CURRENT_STATUS:MOVE_TO_TARGET",
                                             "MOVE_TO_TARGET:arrived at target 1"};
  EXPECT_EQ(heard, expected);
}

// A recorded session replays to OpenIGTLink clients too: its states, no commands.
TEST(BrpE2E, ARecordedSessionReplaysToSlicer) {
  ServerProcess live(171, withApproval({"--controller-speed", "40000"}));
  {
    Navigation nav(live.igtlPort());
    ASSERT_NO_FATAL_FAILURE(nav.arrived());
  }
  ASSERT_EQ(live.stop(), 0);
  const std::string session = live.sessionDir().string();
  ServerProcess replay(
      172, ServerProcess::Program{
               {IGNAV_SERVER_EXE, "--config", IGNAV_SOURCE_DIR "/configs/server.yaml", "--domain",
                "172", "--replay", session, "--speed", "max", "--igtl-port", "0"},
               "ignav-server replayed"});
  ASSERT_GT(replay.igtlPort(), 0);
  Navigation nav(replay.igtlPort());
  nav.client().ignore({});
  ASSERT_NO_FATAL_FAILURE(nav.expectCurrentStatus("MOVE_TO_TARGET"));
  const auto reg = nav.expectTransform("ImageToRobot");
  EXPECT_LT((reg.matrix - calibration()).cwiseAbs().maxCoeff(), 1e-5);
  const auto tip = nav.expectTransform("NeedleTipToImage");
  const Eigen::Vector3d target = targetRas(kReachableRobot_mm).topRightCorner<3, 1>();
  EXPECT_LT((tip.matrix.topRightCorner<3, 1>() - target).norm(), 0.05);
  nav.client().sendGetTransform("CURRENT_POSITION");
  EXPECT_EQ(nav.expectTransform("CURRENT_POSITION").matrix, tip.matrix);
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("EMERGENCY", "MOVE_TO_TARGET", 1, 13, "read_only"));
}

std::size_t igtlClients(protocol::Client& c) {
  c.poll();
  return stateCount(c.state(), "health", "igtl_clients").value_or(99);
}

// A bare TCP connection to the bridge (no OpenIGTLink client), for what a library would not do:
// a receive buffer set before the handshake, a close that sends nothing. -1 on failure.
int connectLoopback(int port, int receive_buffer_bytes = 0) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  if (receive_buffer_bytes > 0) {
    ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receive_buffer_bytes, sizeof receive_buffer_bytes);
  }
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// A client that vanishes, and one that stops reading, are let go within the timeout; the
// others are served on.
TEST(BrpE2E, DroppedAndStalledClientsAreNoticedWithinTheTimeout) {
  ServerProcess server(173, {"--igtl-timeout", "1"});
  auto viewer = server.client("viewer");
  {
    Navigation nav(server.igtlPort());
    ASSERT_NO_FATAL_FAILURE(nav.expectOpening());
    viewer->waitFor([](const json& s) { return stateCount(s, "health", "igtl_clients") == 1u; },
                    5s);
  }  // gone (its process would close the socket the same way when killed)
  viewer->waitFor([](const json& s) { return stateCount(s, "health", "igtl_clients") == 0u; }, 5s);
  EXPECT_EQ(igtlClients(*viewer), 0u);

  // A client that asks and asks but reads nothing, with a small receive buffer.
  const int fd = connectLoopback(server.igtlPort(), 4096);
  ASSERT_GE(fd, 0) << std::strerror(errno);
  auto query = igtl::GetStatusMessage::New();
  query->SetDeviceName("CURRENT_STATUS");
  query->Pack();
  std::string burst;
  for (int i = 0; i < 5000; ++i)
    burst.append(static_cast<const char*>(query->GetPackPointer()), query->GetPackSize());
  const auto sent = std::chrono::steady_clock::now();
  for (std::size_t at = 0; at < burst.size();) {
    const ssize_t n = ::send(fd, burst.data() + at, burst.size() - at, MSG_NOSIGNAL);
    if (n <= 0) break;  // the server let it go already
    at += static_cast<std::size_t>(n);
  }
  viewer->waitFor([](const json& s) { return stateCount(s, "health", "igtl_clients") == 1u; }, 5s);
  // Let go within the 1 s timeout (and the watchdog's 0.1 s tick), with room for a slow machine.
  viewer->waitFor([](const json& s) { return stateCount(s, "health", "igtl_clients") == 0u; }, 10s);
  const double after_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  EXPECT_EQ(igtlClients(*viewer), 0u);
  EXPECT_LT(after_s, 5.0);
  EXPECT_NE(server.serverLog().find("nothing we sent was read"), std::string::npos)
      << server.serverLog();
  ::close(fd);
  // Still serving.
  Navigation next(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(next.expectOpening());
  EXPECT_TRUE(server.alive());
}

// A client whose host vanished without a word (cable pulled, its machine crashed): no FIN, no
// RST, and the server has nothing to send it, so only the server's keep-alive probes can find
// out. The client's socket is closed in TCP repair mode, which makes the kernel forget it
// silently (CAP_NET_ADMIN); the first probe then meets no connection. Without keep-alive the
// server would count the client forever.
TEST(BrpE2E, AClientWhoseHostVanishedSilentlyIsLetGoByKeepAlive) {
  const double timeout_s = 2.0;  // keep-alive: first probe after 1 s idle
  ServerProcess server(176, {"--igtl-timeout", "2"});
  auto viewer = server.client("viewer");
  const int fd = connectLoopback(server.igtlPort());
  ASSERT_GE(fd, 0) << std::strerror(errno);
  viewer->waitFor([](const json& s) { return stateCount(s, "health", "igtl_clients") == 1u; }, 5s);
  const int on = 1;
  if (::setsockopt(fd, IPPROTO_TCP, TCP_REPAIR, &on, sizeof on) != 0) {
    ::close(fd);
    GTEST_SKIP() << "TCP_REPAIR needs CAP_NET_ADMIN: " << std::strerror(errno);
  }
  const auto vanished = std::chrono::steady_clock::now();
  ::close(fd);  // in repair mode: nothing goes on the wire
  viewer->waitFor([](const json& s) { return stateCount(s, "health", "igtl_clients") == 0u; }, 15s);
  const double after_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - vanished).count();
  EXPECT_LT(after_s, timeout_s + 1.0) << "let go only after " << after_s << " s";
  // Found by a probe (the reset), not by a close the client never sent.
  const std::string log = server.serverLog();
  EXPECT_EQ(log.find("closed by the client"), std::string::npos) << log;
  EXPECT_NE(log.find("dropped: Connection reset by peer"), std::string::npos) << log;
  Navigation next(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(next.expectOpening());
}

// Garbage on the port costs the sender its message, not the server its state.
TEST(BrpE2E, MalformedMessagesAreAnsweredAndChangeNothing) {
  ServerProcess server(174);
  Navigation nav(server.igtlPort());
  ASSERT_NO_FATAL_FAILURE(nav.expectOpening());
  auto cmd = igtl::StringMessage::New();
  cmd->SetDeviceName("CMD_0001");
  cmd->SetString("EMERGENCY");
  cmd->Pack();
  std::string bytes(static_cast<const char*>(cmd->GetPackPointer()), cmd->GetPackSize());
  bytes.back() ^= 0x01;  // the CRC no longer matches: not an emergency stop of anyone's
  nav.client().sendRaw(bytes.data(), static_cast<int>(bytes.size()));
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("BAD_MESSAGE", 12, "bad_message"));
  nav.client().sendTransform("CLB_0002", Eigen::Matrix4d::Zero());  // not a registration
  auto ack = nav.expectTransform("ACK_0002");
  ASSERT_NO_FATAL_FAILURE(nav.expectStatus("CALIBRATION", 10, "not_similarity"));
  auto viewer = server.client("viewer");
  EXPECT_EQ(stateText(viewer->state(), "workflow", "phase"), "imaging");
  ASSERT_NO_FATAL_FAILURE(nav.commandExpect("START_UP", "START_UP", 1, 1));
}

// The scripted client a site uses without Slicer (tools/ignav-igtl): its transcript is the
// protocol's exact sequence.
TEST(BrpE2E, TheScriptedClientToolSpeaksTheProtocol) {
  ServerProcess server(175);
  const std::string cmd = std::string(IGNAV_IGTL_EXE) + " --port " +
                          std::to_string(server.igtlPort()) + " cmd:START_UP get-status 2>&1";
  FILE* pipe = ::popen(cmd.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::vector<json> lines;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe))
    lines.push_back(json::parse(buf));
  ASSERT_EQ(::pclose(pipe), 0);
  std::vector<std::string> seen;
  for (const auto& l : lines) {
    std::string what = (l.value("sent", false) ? ">" : "<") + l["device"].get<std::string>();
    if (l.contains("text")) what += " " + l["text"].get<std::string>();
    if (l.contains("code")) what += " " + std::to_string(l["code"].get<int>());
    seen.push_back(what);
  }
  const std::vector<std::string> expected = {
      "<CURRENT_STATUS 1", ">CMD_0001 START_UP", "<ACK_0001 START_UP", "<CURRENT_STATUS 1",
      "<START_UP 1",       ">CURRENT_STATUS",    "<CURRENT_STATUS 1"};
  EXPECT_EQ(seen, expected);
}

}  // namespace
}  // namespace ignav::brp_test
