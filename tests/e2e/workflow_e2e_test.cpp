// The planning workflow end to end: a real ignav-server process, real Cyclone DDS on loopback,
// one DDS domain per test. Numbers are checked against the modules run locally (kinematics,
// the phantom's true transform), not against what the server prints about itself.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>

#include <fmt/format.h>
#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "ignav/config/robot_config.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "server_process.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using protocol::Client;
using protocol::CommandArgs;
using namespace std::chrono_literals;

config::Robot paperRobot() {
  return config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml").value();
}

void loadPhantomAndRegister(Client& c) {
  ASSERT_TRUE(c.send("load_volume", {"phantom:", {}, {}}).accepted);
  c.waitFor([](const json& s) { return s.contains("volume") && s["volume"]["status"] == "loaded"; },
            60s);
  const auto r = c.send("auto_fiducials");
  ASSERT_TRUE(r.accepted) << r.message;
  // State topics are independent: wait for the registration sample itself, not only the phase.
  c.waitFor(
      [](const json& s) {
        return s["workflow"]["phase"] == "planning" && s.contains("registration") &&
               s["registration"]["status"] == "registered";
      },
      10s);
}

TEST(WorkflowE2E, FullPlanningWorkflow) {
  ServerProcess server(41);
  auto c = server.client("e2e-full");
  EXPECT_EQ(c->state()["workflow"]["phase"], "imaging");
  loadPhantomAndRegister(*c);
  c->waitFor([](const json& s) { return s.contains("registration"); }, 5s);
  const json reg = c->state()["registration"];
  EXPECT_EQ(reg["status"], "registered");
  EXPECT_TRUE(reg["auto_detected"].get<bool>());
  EXPECT_LT(reg["fre_mm"].get<double>(), 0.1);

  // The registration matches the phantom's true pose (computed here, independently).
  const auto robot = paperRobot();
  const auto truth =
      registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan).value();
  const Eigen::Matrix4d m = imageToRobot(c->state());
  const Eigen::Matrix4d diff = m - truth.image_to_robot_true;
  EXPECT_LT(diff.block(0, 0, 3, 3).norm(), 2e-3);
  EXPECT_LT(diff.block(0, 3, 3, 1).norm(), 0.3);

  // A reachable target, clicked in LPS: joints and steps as the kinematics give them here.
  const Eigen::Vector3d goal_robot(8.0, 12.0, -175.0);
  const Eigen::Vector3d click = lpsOf(c->state(), goal_robot);
  auto r = c->send("add_target", {"", {click}, {}});
  ASSERT_TRUE(r.accepted) << r.message;
  {
    // Durable before acknowledged: the journal already holds the command when its reply comes.
    std::ifstream journal(server.sessionDir() / "journal.jsonl");
    bool found = false;
    for (std::string line; std::getline(journal, line);) {
      const json record = json::parse(line);
      found |= record.value("input", "") == "add_target" &&
               record.value("request_id", std::uint64_t{0}) == r.request_id;
    }
    EXPECT_TRUE(found) << "add_target #" << r.request_id << " is not in the journal";
  }
  const std::string id = std::to_string(r.target_id);
  c->waitFor([&](const json& s) { return s["targets"].contains(id); }, 5s);
  const json t = c->state()["targets"][id];
  EXPECT_EQ(t["status"], "planned");
  const Eigen::Vector3d robot_mm(t["robot"][0], t["robot"][1], t["robot"][2]);
  EXPECT_LT((robot_mm - goal_robot).norm(), 1e-6);  // the same transform both ways
  const auto expected = robot.kinematics.inverse(robot_mm).value();
  EXPECT_NEAR(t["joints"][0].get<double>(), expected.joints.theta_c_rad, 1e-9);
  EXPECT_NEAR(t["joints"][1].get<double>(), expected.joints.z_c_mm, 1e-9);
  EXPECT_NEAR(t["joints"][2].get<double>(), expected.joints.z_s_mm, 1e-9);
  const auto steps = robot.transmission.toSteps(expected.joints).steps;
  for (int a = 0; a < 3; ++a)
    EXPECT_EQ(t["steps"][a].get<long long>(), steps.motor[a]);
  EXPECT_GT(t["tre_mm"].get<double>(), 0.0);

  // An unreachable one says why, in millimetres.
  r = c->send("add_target", {"", {lpsOf(c->state(), {40.0, 0.0, -180.0})}, {}});
  ASSERT_TRUE(r.accepted);
  EXPECT_NE(r.message.find("beyond the maximum radius 26.535 mm"), std::string::npos) << r.message;
  const auto lock = c->send("lock_plan");
  EXPECT_FALSE(lock.accepted);
  EXPECT_EQ(lock.error_code, "unreachable_targets");
  ASSERT_TRUE(c->send("remove_target", {"", {}, {r.target_id}}).accepted);
  ASSERT_TRUE(c->send("lock_plan").accepted);
  c->waitFor([](const json& s) { return phaseIs(s, "plan_locked"); }, 5s);
  EXPECT_FALSE(c->send("add_target", {"", {click}, {}}).accepted);  // locked
  ASSERT_TRUE(c->send("unlock_plan").accepted);

  // A slice through the target: the PNG decodes and its centre pixel maps to the click.
  protocol::SliceArgs sa;
  sa.view = "coronal";
  sa.centre_lps = click;
  sa.size_px = 256;
  sa.pixel_mm = 0.25;
  const auto slice = c->slice(sa);
  ASSERT_TRUE(slice.ok) << slice.message;
  const cv::Mat img = cv::imdecode(slice.png, cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, 256);
  ASSERT_EQ(img.rows, 256);
  // The requested centre lands on the central pixel, (size - 1) / 2.
  const Eigen::Vector4d centre = slice.pixel_to_lps * Eigen::Vector4d(127.5, 127.5, 0.0, 1.0);
  EXPECT_LT((centre.head<3>() - click).norm(), 1e-9);

  // The session folder holds the journal and the exports.
  EXPECT_EQ(server.stop(), 0);
  std::ifstream journal(server.sessionDir() / "journal.jsonl");
  std::size_t records = 0;
  for (std::string line; std::getline(journal, line);) {
    EXPECT_TRUE(json::accept(line)) << line;
    ++records;
  }
  EXPECT_GE(records, 8u);
  EXPECT_TRUE(std::filesystem::exists(server.sessionDir() / "image_to_robot.tfm"));
  EXPECT_TRUE(std::filesystem::exists(server.sessionDir() / "targets.mrk.json"));
  std::ifstream report(server.sessionDir() / "report.md");
  const std::string text((std::istreambuf_iterator<char>(report)), {});
  EXPECT_NE(text.find("| T" + id + " | planned |"), std::string::npos) << text;
}

TEST(WorkflowE2E, LateJoinerSeesTheCurrentState) {
  ServerProcess server(42);
  auto first = server.client("e2e-first");
  loadPhantomAndRegister(*first);
  const auto r = first->send("add_target", {"", {lpsOf(first->state(), {5, 10, -170})}, {}});
  ASSERT_TRUE(r.accepted);
  // A client that joins now gets phase, registration and the target without asking.
  auto late = server.client("e2e-late");
  late->waitFor(
      [&](const json& s) {
        return s["workflow"]["phase"] == "planning" && s.contains("registration") &&
               s["targets"].contains(std::to_string(r.target_id));
      },
      10s);
  EXPECT_EQ(late->state()["registration"]["status"], "registered");
}

// ping (issue 22: a command added through the one table) over real DDS: the time it reports
// was taken between this client's sending and its receiving the reply (same host, same clock).
TEST(WorkflowE2E, PingAnswersWithTheServersClockAndRevision) {
  ServerProcess server(46);
  auto c = server.client("e2e-ping");
  const auto unix_s = [] {
    return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
        .count();
  };
  for (int i = 0; i < 3; ++i) {
    const double sent_s = unix_s();
    const auto r = c->send("ping");
    const double received_s = unix_s();
    ASSERT_TRUE(r.accepted) << r.message;
    // A typed answer (Reply.server_time_unix_s): the server's clock between sending and receiving.
    EXPECT_GE(r.server_time_unix_s, sent_s);
    EXPECT_LE(r.server_time_unix_s, received_s);
    EXPECT_EQ(r.job, 0u);
    c->poll();
    EXPECT_EQ(c->state()["workflow"]["revision"].get<std::uint64_t>(), r.revision);
  }
}

TEST(WorkflowE2E, EveryRejectionNamesTheProblemAndChangesNothing) {
  ServerProcess server(43);
  auto c = server.client("e2e-reject");
  const auto revision = [&] {
    c->poll();
    return c->state()["workflow"]["revision"].get<std::uint64_t>();
  };
  auto expectRejected = [&](const std::string& command, const CommandArgs& args,
                            const std::string& code, const std::string& text) {
    const auto before = revision();
    const auto r = c->send(command, args);
    EXPECT_FALSE(r.accepted) << command;
    EXPECT_EQ(r.error_code, code) << r.message;
    EXPECT_NE(r.message.find(text), std::string::npos) << r.message;
    std::this_thread::sleep_for(50ms);
    EXPECT_EQ(revision(), before) << command << " changed the state";
  };
  expectRejected("add_target", {"", {{0, 0, 0}}, {}}, "wrong_phase",
                 "add_target is not allowed in imaging");
  expectRejected("load_volume", {"/nonexistent/ct", {}, {}}, "bad_path", "/nonexistent/ct");
  expectRejected("load_volume", {"", {}, {}}, "bad_arguments", "needs a path");
  loadPhantomAndRegister(*c);
  expectRejected("add_target", {"", {{0, std::nan(""), 0}}, {}}, "non_finite", "points[0]");
  expectRejected("remove_target", {"", {}, {999}}, "unknown_target", "no target 999");
  {
    // Outside the phantom's imaged box: the server's phantom grid is centred on LPS (0, 0, 0) and
    // tilted 12° about (1, 1, 0); its box reaches half of dims x spacing from the centre.
    const auto robot = paperRobot();
    const auto spec =
        registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan)
            .value()
            .spec;
    const Eigen::Matrix3d tilt =
        Eigen::AngleAxisd(12.0 * M_PI / 180.0, Eigen::Vector3d(1, 1, 0).normalized()).matrix();
    const Eigen::Vector3d half = 0.5 * spec.spacing_mm.cwiseProduct(Eigen::Vector3d(
                                           spec.dims[0], spec.dims[1], spec.dims[2]));
    const Eigen::Vector3d click(-134, -114, -18), local = tilt.transpose() * click;
    const double outside_mm = (local - local.cwiseMax(-half).cwiseMin(half)).norm();
    expectRejected("add_target", {"", {click}, {}}, "outside_volume",
                   fmt::format("lies {:.1f} mm outside the loaded CT", outside_mm));
  }
  expectRejected("add_target", {"", std::vector<Eigen::Vector3d>(101, {0, 0, 0}), {}}, "oversized",
                 "at most 100");
  expectRejected("set_fiducials", {"", {{0, 0, 0}, {10, 0, 0}, {20, 0, 0}}, {}}, "collinear",
                 "lie within 0.00 mm");
  expectRejected("set_fiducials", {"", {{0, 0, 0}, {10, 0, 0}}, {}}, "bad_arguments",
                 "takes 3 point(s)");
  expectRejected("reorder_targets", {"", {}, {1, 2}}, "bad_order", "exactly once");
  expectRejected("lock_plan", {}, "empty_plan", "no targets");

  // A kind no command has (issue 27: such samples used to be dropped unanswered) gets
  // exactly one reply, unknown_command, and a line in the server's log; nothing changes.
  {
    const auto before = revision();
    protocol::Participant p(server.domain(), loopbackXml(), nullptr, server.robotId());
    protocol::Writer<ignav_msg_Command> commands(
        p, &ignav_msg_Command_desc, protocol::topic::kCommandPlanner, protocol::Qos::kRequest);
    protocol::Reader<ignav_msg_Reply> replies(p, &ignav_msg_Reply_desc, protocol::topic::kReply,
                                              protocol::Qos::kRequest);
    for (int i = 0; i < 1000 && (commands.matched() == 0 || replies.matched() == 0); ++i)
      std::this_thread::sleep_for(10ms);
    ASSERT_GT(commands.matched(), 0u);
    const std::int32_t kinds[] = {4096, 99, std::numeric_limits<std::int32_t>::max(), -1};
    for (std::size_t k = 0; k < std::size(kinds); ++k) {
      protocol::Command odd;
      odd.client_id = "odd-kinds";
      odd.request_id = k + 1;
      odd.kind = kinds[k];
      protocol::Owned<ignav_msg_Command> owned;
      commands.write(protocol::toMsg(odd, owned));
    }
    std::map<std::uint64_t, std::vector<std::string>> answers;  // request id -> error codes
    for (int i = 0; i < 300 && answers.size() < std::size(kinds); ++i) {
      replies.take([&](const ignav_msg_Reply& r) {
        if (std::string(r.client_id) == "odd-kinds") answers[r.request_id].push_back(r.error_code);
      });
      std::this_thread::sleep_for(10ms);
    }
    std::this_thread::sleep_for(200ms);  // a second reply would have come by now
    replies.take([&](const ignav_msg_Reply& r) {
      if (std::string(r.client_id) == "odd-kinds") answers[r.request_id].push_back(r.error_code);
    });
    for (std::size_t k = 0; k < std::size(kinds); ++k) {
      EXPECT_EQ(answers[k + 1], std::vector<std::string>{"unknown_command"}) << kinds[k];
      EXPECT_NE(server.serverLog().find(fmt::format("command kind {} from 'odd-kinds'", kinds[k])),
                std::string::npos)
          << kinds[k];
    }
    EXPECT_EQ(revision(), before);
  }
  // The server is still there and still serves.
  EXPECT_TRUE(c->send("query").accepted);
}

TEST(WorkflowE2E, RepeatedRequestIdIsAnsweredAgainNotExecutedTwice) {
  ServerProcess server(44);
  auto c = server.client("e2e-retry");
  loadPhantomAndRegister(*c);
  const CommandArgs add{"", {lpsOf(c->state(), {5, 10, -170})}, {}};
  const auto first = c->send("add_target", add, 10s, 9000);
  const auto again = c->send("add_target", add, 10s, 9000);
  ASSERT_TRUE(first.accepted);
  EXPECT_EQ(again.accepted, first.accepted);
  EXPECT_EQ(again.target_id, first.target_id);
  EXPECT_EQ(again.revision, first.revision);
  std::this_thread::sleep_for(100ms);
  c->poll();
  EXPECT_EQ(c->state()["targets"].size(), 1u);
}

TEST(WorkflowE2E, TwoClientsAtOnceAndOneKilledMidSession) {
  ServerProcess server(45);
  auto a = server.client("e2e-a");
  auto b = server.client("e2e-b");
  loadPhantomAndRegister(*a);
  // Interleaved commands: each client gets its own replies.
  for (int i = 0; i < 5; ++i) {
    const auto ra = a->send("add_target", {"", {lpsOf(a->state(), {5.0 + i, 10, -170})}, {}});
    const auto rb = b->send("add_target", {"", {lpsOf(a->state(), {-5.0 - i, 10, -180})}, {}});
    ASSERT_TRUE(ra.accepted && rb.accepted);
    EXPECT_NE(ra.target_id, rb.target_id);
  }
  // A third client, a separate process, is killed while it waits for the state.
  const std::string cmd = std::string(IGNAVCTL_EXE) + " --domain " +
                          std::to_string(server.domain()) +
                          " --dds-config " IGNAV_SOURCE_DIR
                          "/configs/dds/loopback.xml watch --seconds 30 >/dev/null 2>&1 & "
                          "sleep 1; kill -9 $!";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  const auto r = a->send("clear_targets");
  EXPECT_TRUE(r.accepted);
  a->waitFor([](const json& s) { return s["targets"].empty(); }, 5s);
  EXPECT_TRUE(b->send("query").accepted);
  EXPECT_EQ(server.stop(), 0);
}

}  // namespace
}  // namespace ignav::e2e
