// Several robots on one DDS domain (docs/DEPLOYMENT.md): real ignav-server processes with robot
// ids, real Cyclone DDS on loopback. Each robot's topics are in its own partition, so a command for
// one never reaches the other; a client that names no robot among several is told which exist; a
// second server with a robot id already served stops before it touches the controller; with DDS
// Security, an approver of one robot cannot publish approvals to another; a site configuration
// chosen by name carries the workflow; ignavctl doctor. Domains 182-185, 188, 193 and 194 (empty).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <fstream>
#include <set>
#include <thread>

#include "ignav/protocol/security.hpp"
#include "server_process.hpp"

namespace ignav::e2e {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using protocol::Client;
using namespace std::chrono_literals;

// ignav-server on configs/server.yaml with `args`, to its end (at most 30 s).
std::string serverCommand(const std::string& args) {
  return "timeout 30 " IGNAV_SERVER_EXE " --config " IGNAV_SOURCE_DIR "/configs/server.yaml " +
         args;
}

std::string ctlCommand(std::uint32_t domain, const std::string& args) {
  return std::string(IGNAVCTL_EXE) + " --domain " + std::to_string(domain) +
         " --dds-config " IGNAV_SOURCE_DIR "/configs/dds/loopback.xml --wait-server 5 " + args;
}

std::unique_ptr<Client> clientOf(const ServerProcess& server, const std::string& id,
                                 const protocol::SecurityIdentity* identity = nullptr) {
  auto c = std::make_unique<Client>(server.domain(), loopbackXml(), id, identity, server.robotId());
  EXPECT_TRUE(c->waitForServer(15s)) << server.robotId();
  c->waitFor([](const json& s) { return s.contains("workflow") && s.contains("health"); }, 10s);
  return c;
}

TEST(RobotsE2E, TwoRobotsShareADomainAndNeverActOnEachOthersCommands) {
  ServerProcess a(182, {"--robot-id", "cell-a"});
  ServerProcess b(182, {"--robot-id", "cell-b"});
  ASSERT_EQ(a.robotId(), "cell-a");
  ASSERT_EQ(b.robotId(), "cell-b");
  auto op_a = clientOf(a, "operator");
  auto op_b = clientOf(b, "operator");
  EXPECT_EQ(op_a->mirror().health->robot_id, "cell-a");
  EXPECT_EQ(op_b->mirror().health->robot_id, "cell-b");
  const auto b_revision = op_b->mirror().workflow->revision;
  const auto b_phase = op_b->mirror().workflow->phase;

  // A whole plan on robot A: B neither hears nor answers any of it.
  const auto target = plannedTarget(*op_a, {8, 12, -175});
  op_a->waitUntil([&](const protocol::StateMirror& m) { return m.targets.count(target) == 1; },
                  10s);
  std::this_thread::sleep_for(1500ms);  // B's Health comes once a second: let it speak again
  op_b->poll();
  EXPECT_EQ(op_b->mirror().workflow->revision, b_revision);
  EXPECT_EQ(op_b->mirror().workflow->phase, b_phase);
  EXPECT_TRUE(op_b->mirror().targets.empty());
  EXPECT_EQ(op_b->mirror().health->commands_accepted, 0u);
  EXPECT_EQ(op_b->mirror().health->commands_rejected, 0u);
  // Each server's journal holds its own commands only.
  std::ifstream journal_b(b.sessionDir() / "journal.jsonl");
  std::string text((std::istreambuf_iterator<char>(journal_b)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find("add_target"), std::string::npos);
  EXPECT_EQ(text.find("load_volume"), std::string::npos);

  // B answers its own client (a query: its revision stays).
  const auto ping_b = op_b->send("ping", {}, 10s);
  EXPECT_TRUE(ping_b.accepted);
  EXPECT_EQ(ping_b.revision, b_revision);

  // Listing: both robots, with their hosts and sessions.
  const auto robots = protocol::discoverRobots(182, loopbackXml(), nullptr, 5s);
  ASSERT_EQ(robots.size(), 2u);
  EXPECT_EQ(robots[0].robot_id, "cell-a");
  EXPECT_EQ(robots[1].robot_id, "cell-b");
  EXPECT_FALSE(robots[0].host.empty());
  EXPECT_NE(robots[0].session_id, robots[1].session_id);
  // Naming none among several is an error that lists them.
  try {
    protocol::chooseRobot(182, loopbackXml(), nullptr, "", 5s);
    ADD_FAILURE() << "chooseRobot chose among two robots";
  } catch (const protocol::RobotNotChosen& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cell-a"), std::string::npos) << what;
    EXPECT_NE(what.find("cell-b"), std::string::npos) << what;
    EXPECT_NE(what.find("--robot"), std::string::npos) << what;
  }

  // The same through ignavctl: robots lists both; a command without --robot changes nothing.
  const auto listed = runCommand(ctlCommand(182, "--json robots"));
  ASSERT_EQ(listed.exit_code, 0) << listed.output;
  const auto listed_json = json::parse(listed.output.substr(listed.output.find('[')));
  ASSERT_EQ(listed_json.size(), 2u);
  EXPECT_EQ(listed_json[0]["robot_id"], "cell-a");
  const auto unnamed = runCommand(ctlCommand(182, "add-target 1,2,3"));
  EXPECT_EQ(unnamed.exit_code, 3) << unnamed.output;
  EXPECT_NE(unnamed.output.find("2 robots on DDS domain 182"), std::string::npos) << unnamed.output;
  const auto named = runCommand(ctlCommand(182, "--robot cell-b --json status"));
  EXPECT_EQ(named.exit_code, 0) << named.output;
  EXPECT_NE(named.output.find("\"robot_id\": \"cell-b\""), std::string::npos) << named.output;
  const auto absent = runCommand(ctlCommand(182, "--robot cell-c ping"));
  EXPECT_EQ(absent.exit_code, 3) << absent.output;
  EXPECT_NE(absent.output.find("no ignav-server for robot 'cell-c'"), std::string::npos)
      << absent.output;
  const auto bad = runCommand(ctlCommand(182, "--robot 'cell*' ping"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("robot id 'cell*' has '*'"), std::string::npos) << bad.output;
  op_a->poll();
  EXPECT_EQ(op_a->mirror().targets.size(), 1u);

  // doctor: both servers among the participants by name, each robot's round trip and clock
  // offset (measured; one host, so no clock check may warn), every check passed.
  const auto doctor = runCommand(ctlCommand(182, "--json doctor --seconds 1"));
  ASSERT_EQ(doctor.exit_code, 0) << doctor.output;
  const auto report = json::parse(doctor.output.substr(doctor.output.find('{')));
  std::set<std::string> names;
  for (const auto& p : report["participants"])
    names.insert(p["name"].get<std::string>().substr(0, 19));
  EXPECT_EQ(names.count("ignav-server cell-a"), 1u) << report.dump();
  EXPECT_EQ(names.count("ignav-server cell-b"), 1u) << report.dump();
  ASSERT_EQ(report["robots"].size(), 2u) << report.dump();
  for (const auto& r : report["robots"]) {
    EXPECT_GT(r["round_trip_ms"]["median"].get<double>(), 0.0);
    EXPECT_TRUE(r.contains("clock_offset_ms")) << r.dump();
    EXPECT_EQ(r["journal"], "ok");
  }
  EXPECT_TRUE(report["checks"].empty()) << report.dump();
  // On an empty domain it says so and exits 3.
  const auto empty = runCommand(ctlCommand(194, "doctor --seconds 0.5"));
  EXPECT_EQ(empty.exit_code, 3) << empty.output;
  EXPECT_NE(empty.output.find("nothing on DDS domain 194"), std::string::npos) << empty.output;
}

TEST(RobotsE2E, ASecondServerWithARobotIdAlreadyServedStopsBeforeTouchingTheController) {
  ServerProcess first(183, {"--robot-id", "twin"});
  auto op = clientOf(first, "operator");
  ASSERT_TRUE(op->send("ping").accepted);
  const auto revision = op->mirror().workflow->revision;

  const fs::path dir = first.sessionDir().string() + "_second";
  fs::remove_all(dir);
  const auto second = runCommand(
      serverCommand("--domain 183 --robot-id twin --no-igtl --session-dir " + dir.string()));
  EXPECT_EQ(second.exit_code, 4) << second.output;
  EXPECT_NE(second.output.find("robot_id 'twin': another ignav-server already serves this robot"),
            std::string::npos)
      << second.output;
  EXPECT_NE(second.output.find(op->mirror().health->session_id), std::string::npos)
      << second.output;
  // It answered queries at once (issue 38: ready before the check ends) but never started its
  // controller, and the new session it gave up is gone with its folder.
  EXPECT_NE(second.output.find("this one did not touch the controller"), std::string::npos)
      << second.output;
  EXPECT_EQ(second.output.find("controller simulated: connecting"), std::string::npos)
      << second.output;
  EXPECT_FALSE(fs::exists(dir)) << second.output;
  fs::remove_all(dir);

  // The first serves on, unchanged.
  const auto again = op->send("ping");
  EXPECT_TRUE(again.accepted);
  EXPECT_EQ(again.revision, revision);
  EXPECT_TRUE(first.alive());
}

TEST(RobotsE2E, ASecondServerWhoseSessionFolderHasTheSameNameIsStillASecondServer) {
  // A session's id is its folder's name. Each server took a Health with its own session id for its
  // own, so two given folders of one name (in two places on one host, or on two hosts) both
  // served the robot.
  ServerProcess first(193, {"--robot-id", "twin"});
  auto op = clientOf(first, "operator");
  ASSERT_TRUE(op->send("ping").accepted);
  const fs::path elsewhere =
      fs::temp_directory_path() / ("ignav_same_name_" + std::to_string(::getpid()));
  const fs::path dir = elsewhere / first.sessionDir().filename();
  ASSERT_NE(dir, first.sessionDir());
  fs::remove_all(elsewhere);
  const auto second = runCommand(
      serverCommand("--domain 193 --robot-id twin --no-igtl --session-dir " + dir.string()));
  fs::remove_all(elsewhere);
  EXPECT_EQ(second.exit_code, 4) << second.output;
  EXPECT_NE(second.output.find("robot_id 'twin': another ignav-server already serves this robot"),
            std::string::npos)
      << second.output;
  EXPECT_EQ(second.output.find("controller simulated: connecting"), std::string::npos)
      << second.output;
  EXPECT_TRUE(op->send("ping").accepted);
  EXPECT_TRUE(first.alive());
}

TEST(RobotsE2E, TwoServersThatMissedEachOtherAtStartLeaveTheOlderServing) {
  // No listening at start (as when a network that was split is joined): they meet once running,
  // and the later one halts and stops within a Health period or two.
  ServerProcess older(184, {"--robot-id", "twin", "--robot-id-check-ms", "0"});
  std::this_thread::sleep_for(50ms);
  const fs::path dir = older.sessionDir().string() + "_later";
  fs::remove_all(dir);
  const auto later = runCommand(
      serverCommand("--domain 184 --robot-id twin --robot-id-check-ms 0 --no-igtl --session-dir " +
                    dir.string()));
  EXPECT_EQ(later.exit_code, 4) << later.output;
  EXPECT_NE(later.output.find("ignav-server ready"), std::string::npos) << later.output;
  EXPECT_NE(later.output.find("robot_id 'twin': another ignav-server already serves this robot"),
            std::string::npos)
      << later.output;
  EXPECT_NE(later.output.find("halting the robot and stopping"), std::string::npos) << later.output;
  // The halt is journaled: an emergency stop by the server itself.
  std::ifstream journal(dir / "journal.jsonl");
  const std::string records((std::istreambuf_iterator<char>(journal)),
                            std::istreambuf_iterator<char>());
  EXPECT_NE(records.find("\"emergency_stop\""), std::string::npos) << records;
  fs::remove_all(dir);
  auto op = clientOf(older, "operator");
  EXPECT_TRUE(op->send("ping").accepted);
  EXPECT_TRUE(older.alive());
  // The older one says so at its next Health tick.
  for (int i = 0; i < 30 && older.serverLog().find("a later ignav-server") == std::string::npos;
       ++i) {
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_NE(older.serverLog().find("a later ignav-server with this robot id appeared"),
            std::string::npos)
      << older.serverLog();
}

TEST(RobotsE2E, AMisconfiguredRobotIdOrDomainIsRefusedAtStartNamingTheSetting) {
  const std::string server = serverCommand(
      "--no-igtl --session-dir " + (fs::temp_directory_path() / "ignav_misconfigured").string());
  const auto spaced = runCommand(server + " --domain 182 --robot-id 'cell a'");
  EXPECT_EQ(spaced.exit_code, 2) << spaced.output;
  EXPECT_NE(spaced.output.find("robot_id: 'cell a' has ' '"), std::string::npos) << spaced.output;
  const auto wildcard = runCommand(server + " --domain 182 --robot-id 'cell*'");
  EXPECT_EQ(wildcard.exit_code, 2) << wildcard.output;
  EXPECT_NE(wildcard.output.find("robot_id: 'cell*' has '*'"), std::string::npos)
      << wildcard.output;
  const auto far = runCommand(server + " --domain 233");
  EXPECT_EQ(far.exit_code, 2) << far.output;
  EXPECT_NE(far.output.find("dds.domain_id: 233 is not within 0..232"), std::string::npos)
      << far.output;
  // In the file: the same checks, and an unknown key under dds: named.
  const fs::path config = fs::temp_directory_path() / "ignav_misconfigured.yaml";
  std::ofstream(config) << "server:\n  robot_config: " IGNAV_SOURCE_DIR
                           "/configs/robots/torabi2014.yaml\n  robot_id: ''\n";
  const auto empty =
      runCommand(std::string("timeout 30 " IGNAV_SERVER_EXE " --config ") + config.string());
  EXPECT_EQ(empty.exit_code, 2) << empty.output;
  EXPECT_NE(empty.output.find("server.robot_id: '' is empty"), std::string::npos) << empty.output;
  std::ofstream(config) << "server:\n  robot_config: " IGNAV_SOURCE_DIR
                           "/configs/robots/torabi2014.yaml\n  dds:\n    domian_id: 3\n";
  const auto typo =
      runCommand(std::string("timeout 30 " IGNAV_SERVER_EXE " --config ") + config.string());
  EXPECT_EQ(typo.exit_code, 2) << typo.output;
  EXPECT_NE(typo.output.find("server.dds.domian_id: unknown key"), std::string::npos)
      << typo.output;
  fs::remove(config);
  EXPECT_FALSE(fs::exists(fs::temp_directory_path() / "ignav_misconfigured"));
}

TEST(RobotsE2E, ASiteConfigurationChosenByNameCarriesTheWorkflow) {
  // site-unicast on this host's loopback interface, with itself as the one peer: the shipped
  // site configuration, filled in by the server and by ignavctl from their own options.
  ServerProcess server(
      188, {"--dds-config", "site-unicast", "--dds-interface", "lo", "--dds-peer", "127.0.0.1"});
  const auto listed = runCommand(std::string(IGNAVCTL_EXE) +
                                 " --domain 188 --dds-config site-unicast --dds-interface lo"
                                 " --dds-peer 127.0.0.1 --wait-server 5 robots");
  EXPECT_EQ(listed.exit_code, 0) << listed.output;
  EXPECT_NE(listed.output.find("robot-1"), std::string::npos) << listed.output;
  const auto pinged = runCommand(std::string(IGNAVCTL_EXE) +
                                 " --domain 188 --dds-config site-unicast --dds-interface lo"
                                 " --dds-peer 127.0.0.1 --wait-server 5 load phantom");
  EXPECT_EQ(pinged.exit_code, 0) << pinged.output;
  // A wrong interface: the setting is named, the host's interfaces listed, nothing starts.
  const auto wrong = runCommand(serverCommand(
      "--domain 188 --dds-config site-unicast --dds-interface ens99x --dds-peer 127.0.0.1 "
      "--session-dir " +
      (fs::temp_directory_path() / "ignav_wrong_interface").string()));
  EXPECT_EQ(wrong.exit_code, 2) << wrong.output;
  EXPECT_NE(wrong.output.find("dds.interface: 'ens99x' is not a network interface of this host"),
            std::string::npos)
      << wrong.output;
  EXPECT_FALSE(fs::exists(fs::temp_directory_path() / "ignav_wrong_interface"));
  const auto client =
      runCommand(std::string(IGNAVCTL_EXE) +
                 " --domain 188 --dds-config site-multicast --wait-server 1 robots");
  EXPECT_NE(client.exit_code, 0) << client.output;
  EXPECT_NE(client.output.find("needs the network interface: set dds.interface"), std::string::npos)
      << client.output;
}

// With DDS Security: identities scoped to one robot (make-test-pki.sh --robot).
TEST(RobotsE2E, AnApproverOfOneRobotCannotApproveAnothersMotion) {
  const fs::path pki =
      fs::temp_directory_path() / ("ignav_robot_pki_" + std::to_string(::getpid()));
  fs::remove_all(pki);
  ASSERT_EQ(std::system((IGNAV_SOURCE_DIR "/configs/security/make-test-pki.sh " + pki.string() +
                         " --robot cell-a --robot cell-b >/dev/null")
                            .c_str()),
            0);
  auto subject = [&](const fs::path& folder) {
    std::ifstream in(folder / "subject.txt");
    std::string s;
    std::getline(in, s);
    return s;
  };
  const fs::path a_approver = pki / "robots/cell-a/approver";
  const fs::path b_approver = pki / "robots/cell-b/approver";
  // Robot A's server even lists B's approver (a mistake in its config): DDS Security still
  // keeps B's identity out of A's partition.
  ServerProcess a(185, {"--robot-id", "cell-a", "--identity",
                        (pki / "robots/cell-a/service").string(), "--approver", subject(a_approver),
                        "--approver", subject(b_approver), "--controller-speed", "40000"});
  const auto planner_id = protocol::identityFromFolder((pki / "robots/cell-a/planner").string());
  auto planner = clientOf(a, "console", &planner_id);
  lockedPlanTo(*planner, {8, 12, -175});
  planner->waitFor([](const json& s) { return stateText(s, "approval", "status") == "pending"; },
                   10s);

  // B's approver (another process: one identity per process): refused by DDS Security.
  const auto refused = runCommand(
      ctlCommand(185, "--robot cell-a --identity " + b_approver.string() + " approve --yes"));
  EXPECT_NE(refused.exit_code, 0) << refused.output;
  EXPECT_NE(refused.output.find("not allowed by DDS Security"), std::string::npos)
      << refused.output;
  EXPECT_NE(refused.output.find("robot 'cell-a'"), std::string::npos) << refused.output;
  planner->poll();
  EXPECT_EQ(stateText(planner->state(), "approval", "status"), "pending");
  EXPECT_TRUE(phaseIs(planner->state(), "plan_locked"));

  // A's approver releases it.
  const auto approved = runCommand(
      ctlCommand(185, "--robot cell-a --identity " + a_approver.string() + " approve --yes"));
  ASSERT_EQ(approved.exit_code, 0) << approved.output;
  planner->waitFor([](const json& s) { return phaseIs(s, "at_target"); }, 30s);
  fs::remove_all(pki);
}

}  // namespace
}  // namespace ignav::e2e
