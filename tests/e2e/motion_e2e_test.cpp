// Approval-gated motion end to end: real ignav-server processes over Cyclone DDS on loopback,
// driving the simulated controller or a Galil DMC look-alike (dmc-emulator) over TCP.
#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <thread>

#include "ignav/config/robot_config.hpp"
#include "server_process.hpp"
#include "support/dmc_emulator.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using protocol::Client;
using namespace std::chrono_literals;

const config::Robot& paperRobot() {
  static const config::Robot robot =
      config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml").value();
  return robot;
}

// The steps a target's joints give through the transmission, computed here from the robot-frame
// point (our own IK and transmission, not the server's numbers).
std::array<std::int64_t, 3> stepsFor(const Eigen::Vector3d& robot_mm) {
  const auto ik = paperRobot().kinematics.inverse(robot_mm);
  EXPECT_TRUE(ik.ok() && ik->reachable());
  return paperRobot().transmission.toSteps(ik->joints).steps.motor;
}

std::array<std::int64_t, 3> steps(const json& j) {
  return {j[0].get<std::int64_t>(), j[1].get<std::int64_t>(), j[2].get<std::int64_t>()};
}

std::string journalText(const ServerProcess& server) {
  std::ifstream in(server.sessionDir() / "journal.jsonl");
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(MotionE2E, ApprovedMotionArrivesAtTheTargetsStepsAndNothingElseMoves) {
  ServerProcess server(61, {"--controller-speed", "40000"});
  auto op = server.client("operator");
  auto visitor = server.client("visitor");
  const Eigen::Vector3d target_robot(8, 12, -175);
  const auto id = lockedPlanTo(*op, target_robot);
  const json shown = op->state()["approval"];
  const auto revision = op->state()["workflow"]["revision"];
  EXPECT_EQ(shown["target_id"], id);
  EXPECT_EQ(shown["approvers"], json::array({"operator"}));
  EXPECT_EQ(shown["digest"].get<std::string>().size(), 64u);

  // Refused: a client that may not approve, a wrong digest, a stale plan id. Nothing moves.
  auto r = visitor->approve(shown["plan_id"], shown["digest"]);
  EXPECT_EQ(r.error_code, "not_approver") << r.message;
  std::string wrong = shown["digest"];
  wrong[10] = wrong[10] == 'a' ? 'b' : 'a';
  EXPECT_EQ(op->approve(shown["plan_id"], wrong).error_code, "wrong_digest");
  EXPECT_EQ(op->approve(shown["plan_id"].get<std::uint64_t>() + 1, shown["digest"]).error_code,
            "stale_plan");
  std::this_thread::sleep_for(100ms);
  op->poll();
  EXPECT_EQ(op->state()["workflow"]["revision"], revision);
  EXPECT_EQ(steps(op->state()["motion"]["steps"]), (std::array<std::int64_t, 3>{0, 0, 0}));

  r = approveShown(*op);
  ASSERT_TRUE(r.accepted) << r.message;
  // The journal held the approval before its reply was sent.
  EXPECT_NE(journalText(server).find("\"request_id\":" + std::to_string(r.request_id)),
            std::string::npos);
  op->waitFor([](const json& s) { return phaseIs(s, "at_target"); }, 30s);
  op->waitFor([](const json& s) { return stateText(s, "motion", "state") == "idle"; }, 5s);
  const json& t = op->state()["targets"][std::to_string(id)];
  EXPECT_EQ(t["status"], "reached");
  // configs/server.yaml picks agar: every target carries the model's predicted cannula drift.
  EXPECT_NE(op->state()["robot"]["tissue"].get<std::string>().find("agar"), std::string::npos);
  EXPECT_TRUE(t["predicted_deviation_mm"].is_number()) << t.dump();
  const Eigen::Vector3d robot_mm(t["robot"][0], t["robot"][1], t["robot"][2]);
  EXPECT_EQ(steps(op->state()["motion"]["steps"]), stepsFor(robot_mm));
  const json& tip = op->state()["motion"]["tip_robot"];
  EXPECT_LT((Eigen::Vector3d(tip[0], tip[1], tip[2]) - robot_mm).norm(), 0.15);
  // The report has the slices through the reached target, and says when it was reached. (The
  // server writes them after its replies and state: wait for the report that lists them.)
  // (A fresh stream each time: streaming an empty file, caught mid-rewrite, sets failbit, and a
  // reused stream then stays empty.)
  std::stringstream report;
  for (int i = 0; i < 200 && report.str().find("_reached.png)") == std::string::npos; ++i) {
    std::this_thread::sleep_for(25ms);
    report = std::stringstream();
    report << std::ifstream(server.sessionDir() / "report.md").rdbuf();
  }
  for (const char* view : {"coronal", "axial"}) {
    const auto png =
        server.sessionDir() / "report" / ("T" + std::to_string(id) + "_" + view + "_reached.png");
    const cv::Mat image = cv::imread(png.string());
    EXPECT_EQ(image.cols, 384) << png;
    EXPECT_EQ(image.rows, 384) << png;
  }
  EXPECT_NE(report.str().find("_reached.png)"), std::string::npos) << report.str();
  EXPECT_NE(report.str().find("| 1 | T" + std::to_string(id) + " | reached |"), std::string::npos)
      << report.str();

  // The last motion retracts the stylet; then the procedure is done.
  op->waitFor(
      [](const json& s) {
        return s["approval"]["status"] == "pending" && s["approval"]["target_id"] == 0;
      },
      5s);
  ASSERT_TRUE(approveShown(*op).accepted);
  op->waitFor([](const json& s) { return phaseIs(s, "done"); }, 30s);
  op->waitFor([](const json& s) { return stateText(s, "motion", "state") == "idle"; }, 5s);
  EXPECT_LT(std::abs(op->state()["motion"]["joints"][2].get<double>()),
            1.0 / paperRobot().transmission.styletStepsPerMm());
}

TEST(MotionE2E, EmergencyStopMidMoveHaltsTheRobotWhereItIs) {
  ServerProcess server(62, {"--controller-speed", "2000"});  // a slow move, seconds long
  auto op = server.client("operator");
  lockedPlanTo(*op, {-10, 15, -190});
  ASSERT_TRUE(approveShown(*op).accepted);
  op->waitFor(
      [](const json& s) {
        return s.contains("motion") && s["motion"]["state"] == "moving" &&
               s["motion"]["steps"][0].get<std::int64_t>() > 500;
      },
      10s);
  const auto goal = steps(op->state()["motion"]["goal_steps"]);
  const auto r = op->emergencyStop();
  ASSERT_TRUE(r.accepted) << r.message;
  op->waitFor([](const json& s) { return phaseIs(s, "emergency"); }, 5s);
  op->waitFor([](const json& s) { return stateText(s, "motion", "state") == "idle"; }, 5s);
  const auto halted = steps(op->state()["motion"]["steps"]);
  EXPECT_NE(halted, goal);
  std::this_thread::sleep_for(200ms);
  op->poll();
  EXPECT_EQ(steps(op->state()["motion"]["steps"]), halted);  // it stays where it stopped

  // Leaving: reset checks the position (on the interrupted move), resume plans from there, and a
  // new approval takes the robot to the target's exact steps.
  EXPECT_EQ(op->send("resume").error_code, "wrong_phase");
  const auto reset = op->send("reset_emergency");
  ASSERT_TRUE(reset.accepted) << reset.message;
  ASSERT_TRUE(op->send("resume").accepted);
  op->waitFor(
      [](const json& s) {
        return s["approval"]["status"] == "pending" && phaseIs(s, "plan_locked");
      },
      5s);
  EXPECT_EQ(steps(op->state()["approval"]["from_steps"]), halted);
}

TEST(MotionE2E, ControllerFaultMidMoveOverGalilBecomesTheFaultPhase) {
  // The Galil look-alike's forward limit switch at 5000 steps: the cannula translation to this
  // target needs ~12700 steps on motor 1.
  test::Emulator dmc("--limit-max 5000");
  ServerProcess server(63, {"--controller", "galil:127.0.0.1:" + std::to_string(dmc.port()),
                            "--controller-speed", "40000"});
  auto op = server.client("operator");
  lockedPlanTo(*op, {-10, 15, -190});
  op->waitFor([](const json& s) { return s.contains("motion"); }, 5s);
  EXPECT_EQ(op->state()["motion"]["controller"], "galil 127.0.0.1:" + std::to_string(dmc.port()));
  ASSERT_TRUE(approveShown(*op).accepted);
  op->waitFor([](const json& s) { return phaseIs(s, "fault"); }, 30s);
  op->waitFor([](const json& s) { return !stateText(s, "motion", "fault").empty(); }, 5s);
  const std::string fault = op->state()["motion"]["fault"];
  EXPECT_NE(fault.find("forward limit switch at 5000 steps"), std::string::npos) << fault;
  EXPECT_EQ(op->state()["approval"]["status"], "none");
  // Stopped by the switch on its way: the position check passes and the fault is cleared.
  const auto reset = op->send("reset_emergency");
  ASSERT_TRUE(reset.accepted) << reset.message;
  op->waitFor([](const json& s) { return phaseIs(s, "stopped"); }, 5s);
}

TEST(MotionE2E, ServerKilledMidMoveComesBackInFaultAndFinishesAfterThePositionCheck) {
  // A Galil controller outlives the server, as the real one does.
  test::Emulator dmc;
  ServerProcess server(64, {"--controller", "galil:127.0.0.1:" + std::to_string(dmc.port()),
                            "--controller-speed", "5000"});
  std::uint32_t id = 0;
  json old_approval;
  {
    auto op = server.client("operator");
    id = lockedPlanTo(*op, {-10, 15, -190});
    old_approval = op->state()["approval"];
    ASSERT_TRUE(approveShown(*op).accepted);
    op->waitFor(
        [](const json& s) {
          return s.contains("motion") && s["motion"]["steps"][0].get<std::int64_t>() > 500;
        },
        10s);
  }
  server.crash();
  server.start();

  auto op = server.client("operator");
  op->waitFor([](const json& s) { return phaseIs(s, "fault") && s.contains("motion"); }, 20s);
  op->waitFor([](const json& s) { return stateText(s, "motion", "state") == "idle"; }, 10s);
  EXPECT_NE(op->state()["motion"]["fault"].get<std::string>().find("restarted during plan"),
            std::string::npos)
      << op->state()["motion"].dump();
  // The approval given before the crash is dead.
  EXPECT_EQ(op->approve(old_approval["plan_id"], old_approval["digest"]).error_code, "wrong_phase");
  const auto where = steps(op->state()["motion"]["steps"]);
  const auto reset = op->send("reset_emergency");
  ASSERT_TRUE(reset.accepted) << reset.message;
  ASSERT_TRUE(op->send("resume").accepted);
  op->waitFor([](const json& s) { return stateText(s, "approval", "status") == "pending"; }, 5s);
  EXPECT_EQ(steps(op->state()["approval"]["from_steps"]), where);
  EXPECT_NE(op->state()["approval"]["plan_id"], old_approval["plan_id"]);
  ASSERT_TRUE(approveShown(*op).accepted);
  op->waitFor([](const json& s) { return phaseIs(s, "at_target"); }, 60s);
  op->waitFor([](const json& s) { return stateText(s, "motion", "state") == "idle"; }, 5s);
  const json& t = op->state()["targets"][std::to_string(id)];
  const Eigen::Vector3d robot_mm(t["robot"][0], t["robot"][1], t["robot"][2]);
  EXPECT_EQ(steps(op->state()["motion"]["steps"]), stepsFor(robot_mm));
}

// Exit code and output of `ignav-server ARGS` (which must stop by itself: bad options).
std::pair<int, std::string> runServer(const std::string& args) {
  const std::string cmd = std::string(IGNAV_SERVER_EXE) + " " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  char buf[512];
  while (fgets(buf, sizeof buf, p))
    out += buf;
  const int status = pclose(p);
  return {WEXITSTATUS(status), out};
}

TEST(MotionE2E, BadControllerAndApprovalOptionsNameTheKey) {
  const auto dir = std::filesystem::temp_directory_path() / "ignav_bad_options";
  std::filesystem::create_directories(dir);
  const std::string robot = IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml";
  struct Case {
    std::string yaml, expected;
  };
  const std::vector<Case> cases = {
      {"controller: {kind: stepper}",
       "server.controller.kind: 'stepper' is not simulated or galil"},
      {"controller: {speed_steps_s: -5}", "server.controller.speed_steps_s: -5 must be positive"},
      {"controller: {sped: 5}", "server.controller.sped: unknown key"},
      {"approval: {expiry_s: 0}", "server.approval.expiry_s: 0 must be positive"},
      {"planning: {max_targets: 101}", "server.planning.max_targets: 101 is not within 1..100"},
      {"planning: {max_total_rotation_deg: 400}",
       "server.planning.max_total_rotation_deg: 400 is not within (0, 360]"},
      {"openigtlink: {protocol: brp2012}",
       "server.openigtlink.protocol: 'brp2012' is not a BRP revision: slicer"},
  };
  for (const auto& c : cases) {
    const auto file = dir / "server.yaml";
    std::ofstream(file) << "server:\n  robot_config: " << robot << "\n  " << c.yaml << "\n";
    const auto [code, out] = runServer("--config " + file.string() + " --domain 65");
    EXPECT_EQ(code, 2) << c.yaml << ": " << out;
    EXPECT_NE(out.find(c.expected), std::string::npos) << out;
  }
  const auto [tissue_code, tissue_out] =
      runServer("--config " IGNAV_SOURCE_DIR "/configs/server.yaml --domain 65 --tissue liver");
  EXPECT_EQ(tissue_code, 2);
  EXPECT_NE(tissue_out.find("tissue 'liver' is not a profile (there are: agar, none, plastisol)"),
            std::string::npos)
      << tissue_out;
  const auto [code, out] = runServer("--config " IGNAV_SOURCE_DIR
                                     "/configs/server.yaml --domain 65 --controller serial:/dev/x");
  EXPECT_EQ(code, 2);
  EXPECT_NE(out.find("--controller: 'serial:/dev/x' is not simulated or galil:HOST:PORT"),
            std::string::npos)
      << out;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace ignav::e2e
