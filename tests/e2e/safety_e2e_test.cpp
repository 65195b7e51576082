// Safety defects found from outside (issue 38), each shown against real ignav-server processes over
// Cyclone DDS on loopback: an approval bound to its robot and session, one server per session
// folder, an approval judged on a reading taken after it arrived, one-shot reads that wait for
// the server's present, and settings refused before anything is made. Domains 211-216.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fstream>
#include <thread>

#include "server_process.hpp"
#include "support/dmc_emulator.hpp"

namespace ignav::e2e {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using protocol::Client;
using namespace std::chrono_literals;

// A server on `domain` as the given robot, in the given session folder (whose name two servers may
// share), with everything else as ServerProcess starts it.
ServerProcess::Program serverIn(std::uint32_t domain, const std::string& robot_id,
                                const fs::path& session_dir) {
  std::vector<std::string> argv{IGNAV_SERVER_EXE,
                                "--config",
                                IGNAV_SOURCE_DIR "/configs/server.yaml",
                                "--domain",
                                std::to_string(domain),
                                "--robot-id",
                                robot_id,
                                "--robot-id-check-ms",
                                "150",
                                "--no-igtl"};
  if (!session_dir.empty()) argv.insert(argv.end(), {"--session-dir", session_dir.string()});
  return {argv, "ignav-server ready"};
}

// A client of `server` once it holds the server's present (every state topic).
std::unique_ptr<Client> clientOf(const ServerProcess& server, const std::string& id) {
  auto c = server.client(id);
  EXPECT_TRUE(c->waitForPresent(10s)) << server.robotId();
  return c;
}

std::string readFile(const fs::path& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A server.yaml like configs/server.yaml (loopback DDS, the paper's robot, 'operator' approves)
// with sessions under `sessions` and `extra` (settings under server:, a dds: of its own included).
void writeConfig(const fs::path& file, const fs::path& sessions, const std::string& extra = "") {
  std::ofstream out(file);
  out << "server:\n  robot_config: " IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml\n"
      << "  session_root: " << sessions.string() << "\n"
      << "  approval: {approvers: [operator]}\n";
  if (extra.rfind("dds:", 0) != 0) {
    out << "  dds: {config: " IGNAV_SOURCE_DIR "/configs/dds/loopback.xml}\n";
  }
  out << "  " << extra << "\n";
}

// A scratch folder of this test process, removed at the end.
struct Scratch {
  fs::path root;
  explicit Scratch(const std::string& name)
      : root(fs::temp_directory_path() /
             ("ignav_safety_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(root);
    fs::create_directories(root);
  }
  ~Scratch() { fs::remove_all(root); }
};

// 1. Two robots whose session folders have one name and whose plans are the same: before issue 38
// their digests were equal, and cell-d moved on cell-c's approval.
TEST(SafetyE2E, AnApprovalForOneRobotNeverMovesAnotherWhoseFolderAndPlanAreTheSame) {
  Scratch scratch("cross_robot");
  ServerProcess cell_c(211, serverIn(211, "cell-c", scratch.root / "c" / "session"));
  ServerProcess cell_d(211, serverIn(211, "cell-d", scratch.root / "d" / "session"));
  ASSERT_EQ(cell_c.robotId(), "cell-c");
  ASSERT_EQ(cell_d.robotId(), "cell-d");
  auto op_c = clientOf(cell_c, "operator");
  auto op_d = clientOf(cell_d, "operator");
  for (Client* op : {op_c.get(), op_d.get()}) {
    ASSERT_NO_FATAL_FAILURE(lockedPlanTo(*op, {-10, 15, -190}));
  }
  op_c->poll();
  op_d->poll();
  const json shown_c = op_c->state()["approval"];
  const json shown_d = op_d->state()["approval"];
  // The same plan, shown alike (plan id, steps, duration): only the robot and session differ.
  ASSERT_EQ(shown_c["plan_id"], shown_d["plan_id"]);
  ASSERT_EQ(shown_c["summary"], shown_d["summary"]);
  EXPECT_NE(shown_c["digest"], shown_d["digest"]);

  const auto refused =
      op_d->approve(shown_c["plan_id"].get<std::uint64_t>(), shown_c["digest"].get<std::string>());
  EXPECT_FALSE(refused.accepted);
  EXPECT_EQ(refused.error_code, "wrong_digest") << refused.message;
  op_d->poll();
  EXPECT_TRUE(phaseIs(op_d->state(), "plan_locked")) << op_d->state()["workflow"].dump();
  EXPECT_EQ(stateText(op_d->state(), "approval", "status"), "pending");
  // Nothing was sent to cell-d's motors: no approval in its journal.
  EXPECT_EQ(readFile(scratch.root / "d" / "session" / "journal.jsonl").find("\"approve\""),
            std::string::npos);
  // Each robot's own approval still moves it.
  EXPECT_TRUE(approveShown(*op_d).accepted);
}

// 2. A second server started beside a live one on the same session_root (another domain, say a
// manual run beside the service) found the live one's unfinished-session marker and continued its
// session: duplicate revisions in the journal, and the marker deleted on its clean stop.
TEST(SafetyE2E, ASecondServerOnALiveSessionIsRefusedAndACrashedOnesSessionStillRecovers) {
  Scratch scratch("second_server");
  const fs::path root = scratch.root / "sessions";
  const fs::path config = scratch.root / "server.yaml";
  writeConfig(config, root);
  auto program = [&](std::uint32_t domain) {
    auto p = serverIn(domain, "robot-1", {});
    p.argv[2] = config.string();
    return p;
  };
  auto live = std::make_unique<ServerProcess>(212, program(212));
  const fs::path marker = root / ".unfinished-robot-1";
  ASSERT_TRUE(fs::exists(marker));
  fs::path session;
  for (const auto& entry : fs::directory_iterator(root))
    if (entry.is_directory()) session = entry.path();
  ASSERT_FALSE(session.empty());
  auto op = clientOf(*live, "operator");
  const std::string journal_before = readFile(session / "journal.jsonl");
  const std::string marker_before = readFile(marker);

  const auto second = runCommand("timeout 30 " IGNAV_SERVER_EXE " --config " + config.string() +
                                 " --domain 213 --robot-id-check-ms 150 --no-igtl");
  EXPECT_EQ(second.exit_code, 4) << second.output;
  EXPECT_NE(second.output.find("this session folder is in use by another ignav-server (pid " +
                               std::to_string(live->pid())),
            std::string::npos)
      << second.output;
  EXPECT_EQ(second.output.find("continuing it"), std::string::npos) << second.output;
  EXPECT_EQ(second.output.find("ignav-server ready"), std::string::npos) << second.output;
  // The live session is untouched: its journal, its marker, and it still serves.
  EXPECT_EQ(readFile(session / "journal.jsonl"), journal_before);
  EXPECT_EQ(readFile(marker), marker_before);
  EXPECT_TRUE(op->send("ping").accepted);
  EXPECT_TRUE(live->alive());

  // A crash releases the folder: the next server continues that session, as systemd's restart.
  live->crash();
  op.reset();
  live = std::make_unique<ServerProcess>(213, program(213));
  op = clientOf(*live, "operator");
  op->poll();
  EXPECT_EQ(op->state()["health"]["session_dir"].get<std::string>(), session.string());
  // Continued: its journal's record, then server_restarted once the controller is read.
  op->waitFor([](const json& s) { return stateCount(s, "workflow", "revision").value_or(0) >= 2; },
              10s);
  EXPECT_EQ(live->stop(), 0);
  EXPECT_FALSE(fs::exists(marker));  // a clean stop ends the session
  const auto [code, out] = replayVerified(session);
  EXPECT_EQ(code, 0) << out;
}

// A TCP handle of our own on the controller (a DMC takes several): the hand jog a person makes
// with the controller's own terminal while the server drives it.
class ControllerTerminal {
 public:
  explicit ControllerTerminal(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  }
  ~ControllerTerminal() { ::close(fd_); }
  // One command; its reply up to the prompt (':' or '?').
  std::string send(const std::string& command) {
    const std::string line = command + "\r";
    EXPECT_EQ(::send(fd_, line.data(), line.size(), MSG_NOSIGNAL),
              static_cast<ssize_t>(line.size()));
    std::string reply;
    char c = 0;
    while (::recv(fd_, &c, 1, 0) == 1) {
      reply += c;
      if (c == ':' || c == '?') break;
    }
    return reply;
  }
  // Moves motor 1 by `steps` and returns once it is at rest again.
  void jog(int steps) {
    EXPECT_EQ(send("PR" + std::to_string(steps) + ",0,0"), ":");
    EXPECT_EQ(send("BG"), ":");
    for (int i = 0; i < 500 && send("MG _BG").find("1.0000") != std::string::npos; ++i)
      std::this_thread::sleep_for(1ms);
  }

 private:
  int fd_ = -1;
};

// 3. An approval that arrives a moment after the motors were moved by hand was judged on the
// reading from before the jog: accepted, then the executor refused the move and the session ended
// in fault. Now it waits for a reading begun after it arrived, and is refused with nothing else
// changed. Each round jogs and approves at once; the server polls every 200 ms at rest, so the old
// code accepted most rounds.
TEST(SafetyE2E, AnApprovalRightAfterTheMotorsWereMovedByHandIsRefusedWithoutAFault) {
  test::Emulator dmc;
  ServerProcess server(214, {"--controller", "galil:127.0.0.1:" + std::to_string(dmc.port())});
  auto op = server.client("operator");
  ASSERT_NO_FATAL_FAILURE(lockedPlanTo(*op, {-10, 15, -190}));
  ASSERT_EQ(stateText(op->state(), "motion", "lifecycle"), "active");
  ControllerTerminal terminal(dmc.port());
  for (int round = 1; round <= 5; ++round) {
    terminal.jog(3);  // a few steps: over in ~40 ms, between two of the server's readings
    const auto r = approveShown(*op);
    EXPECT_FALSE(r.accepted) << "round " << round << ": accepted with motor 1 three steps off";
    EXPECT_EQ(r.error_code, "controller_changed") << r.message;
    EXPECT_NE(r.message.find("motor 1"), std::string::npos) << r.message;
    op->poll();
    EXPECT_TRUE(phaseIs(op->state(), "plan_locked")) << op->state()["workflow"].dump();
    EXPECT_EQ(stateText(op->state(), "approval", "status"), "pending");
    terminal.jog(-3);  // back where the plan starts
  }
  // Where the plan starts again: an accepted approval is a motion that starts and arrives.
  const auto r = approveShown(*op);
  ASSERT_TRUE(r.accepted) << r.message;
  op->waitFor([](const json& s) { return phaseIs(s, "at_target") || phaseIs(s, "fault"); }, 60s);
  EXPECT_TRUE(phaseIs(op->state(), "at_target")) << op->state()["workflow"].dump();
}

// 5. A reader that had not yet heard the server said something false: `ignavctl approval` printed
// "no motion is waiting for approval" in 4 of 10 runs while one was pending, and a fresh server
// published no Volume, Registration or Verification sample at all.
TEST(SafetyE2E, ALateJoinersOneShotReadsAreAlwaysRight) {
  ServerProcess server(216);
  {
    // A fresh server: every state topic is there, the empty ones included.
    Client late(216, loopbackXml(), "late", nullptr, server.robotId());
    ASSERT_TRUE(late.waitForServer(15s));
    ASSERT_TRUE(late.waitForPresent(10s)) << late.state().dump();
    EXPECT_EQ(late.mirror().volume->status, "none");
    EXPECT_EQ(late.mirror().registration->status, "none");
    EXPECT_EQ(late.mirror().approval->status, "none");
    EXPECT_TRUE(late.mirror().workflow->target_ids.empty());
    EXPECT_TRUE(late.mirror().targets.empty());
  }
  auto op = server.client("operator");
  ASSERT_NO_FATAL_FAILURE(lockedPlanTo(*op, {-10, 15, -190}));
  op->poll();
  const std::string digest = op->state()["approval"]["digest"].get<std::string>();
  const std::string ctl = std::string(IGNAVCTL_EXE) + " --domain 216 --dds-config " +
                          IGNAV_SOURCE_DIR "/configs/dds/loopback.xml --wait-server 10 ";
  for (int run = 0; run < 10; ++run) {
    const auto approval = runCommand(ctl + "approval");
    EXPECT_EQ(approval.exit_code, 0) << approval.output;
    EXPECT_NE(approval.output.find("digest " + digest), std::string::npos)
        << "run " << run << ": " << approval.output;
    const auto motion = runCommand(ctl + "motion");
    EXPECT_EQ(motion.exit_code, 0) << motion.output;
    EXPECT_EQ(motion.output.find("no motion state yet"), std::string::npos) << motion.output;
    const auto targets = runCommand(ctl + "--json targets ls");
    EXPECT_EQ(targets.exit_code, 0) << targets.output;
    // (The output also has ignavctl's warning that security is off, on stderr.)
    const auto listed = json::parse(
        targets.output.substr(std::min(targets.output.find('{'), targets.output.size())), nullptr,
        false);
    EXPECT_TRUE(listed.is_object() && listed.size() == 1)
        << "run " << run << ": " << targets.output;
  }
}

// 6. Every configuration or identity error exits 2 (systemd's unit does not restart on 2) naming
// the key or file, before anything is created. Before issue 38 a bad identity exited 1 after
// making the session folder (restarted every 2 s), and a number of the wrong kind said "yaml-cpp:
// bad conversion" without its key.
TEST(SafetyE2E, EveryBadSettingOrIdentityExitsTwoNamingItAndCreatesNothing) {
  Scratch scratch("bad_settings");
  const fs::path sessions = scratch.root / "sessions";
  const fs::path pki = scratch.root / "pki";
  const fs::path other_pki = scratch.root / "other_pki";
  const std::string make_pki = IGNAV_SOURCE_DIR "/configs/security/make-test-pki.sh ";
  ASSERT_EQ(runCommand(make_pki + pki.string()).exit_code, 0);
  ASSERT_EQ(runCommand(make_pki + other_pki.string() + " --ca-name 'another CA'").exit_code, 0);
  // An identity whose certificate another CA issued; one without its permissions.
  const fs::path foreign = scratch.root / "foreign";
  const fs::path unpermitted = scratch.root / "unpermitted";
  fs::copy(pki / "service", foreign);
  fs::copy_file(other_pki / "service" / "cert.pem", foreign / "cert.pem",
                fs::copy_options::overwrite_existing);
  fs::copy_file(other_pki / "service" / "key.pem", foreign / "key.pem",
                fs::copy_options::overwrite_existing);
  fs::copy(pki / "service", unpermitted);
  fs::remove(unpermitted / "permissions.p7s");

  struct Case {
    std::string yaml;  // under server:
    std::string args;  // on the command line
    std::string expected;
  };
  const std::vector<Case> cases{
      {"dds: {domain_id: -1}", "", "server.dds.domain_id: -1 is not within 0..232"},
      {"dds: {domain_id: 4294967296}", "", "server.dds.domain_id: 4294967296 is not within 0..232"},
      {"dds: {domain_id: 231.5}", "", "server.dds.domain_id: '231.5' is not a whole number"},
      {"controller: {port: twenty}", "", "server.controller.port: 'twenty' is not a whole number"},
      {"planning: {max_targets: [1, 2]}", "",
       "server.planning.max_targets: a list is not a whole number"},
      {"tissue: {name: {a: b}}", "", "server.tissue.name: a map is not a text"},
      {"openigtlink: {enabled: maybe}", "",
       "server.openigtlink.enabled: 'maybe' is not true or false"},
      {"", "--dds-config site-unicast --dds-interface 'lo\"' --dds-peer 127.0.0.1",
       "dds.interface: 'lo\"' is not a network interface name or address"},
      {"", "--dds-config site-unicast --dds-interface lo --dds-peer no-such-host.invalid",
       "dds.peers: 'no-such-host.invalid' does not resolve"},
      {"", "--identity " + foreign.string(), "not accepted by"},
      {"", "--identity " + unpermitted.string(), "permissions.p7s is missing"},
  };
  for (const auto& c : cases) {
    const fs::path config = scratch.root / "server.yaml";
    writeConfig(config, sessions, c.yaml);
    const auto run = runCommand("timeout 30 " IGNAV_SERVER_EXE " --config " + config.string() +
                                " --domain 215 --no-igtl " + c.args);
    EXPECT_EQ(run.exit_code, 2) << c.yaml << c.args << ": " << run.output;
    EXPECT_NE(run.output.find(c.expected), std::string::npos)
        << c.yaml << c.args << ": " << run.output;
    EXPECT_FALSE(fs::exists(sessions)) << c.yaml << c.args << ": a session folder was made";
    fs::remove_all(sessions);
  }
  // An interface that is down: `lo` of a network namespace of our own, where it starts down
  // (Cyclone said only "dds_create_domain: Error"). Needs root, as the network tests do.
  const std::string netns = "ignav_safety_" + std::to_string(::getpid());
  if (::geteuid() == 0 && runCommand("ip netns add " + netns).exit_code == 0) {
    writeConfig(scratch.root / "server.yaml", sessions);
    const auto down =
        runCommand("ip netns exec " + netns + " timeout 30 " IGNAV_SERVER_EXE " --config " +
                   (scratch.root / "server.yaml").string() +
                   " --domain 215 --no-igtl --dds-config site-unicast "
                   "--dds-interface lo --dds-peer 127.0.0.1");
    runCommand("ip netns del " + netns);
    EXPECT_EQ(down.exit_code, 2) << down.output;
    EXPECT_NE(down.output.find("dds.interface: 'lo' is down"), std::string::npos) << down.output;
    EXPECT_FALSE(fs::exists(sessions)) << down.output;
    fs::remove_all(sessions);
  }
  // The identity that is right starts (the checks do not refuse a good one).
  const fs::path config = scratch.root / "server.yaml";
  writeConfig(config, sessions);
  ServerProcess good(
      215, ServerProcess::Program{
               {IGNAV_SERVER_EXE, "--config", config.string(), "--domain", "215", "--no-igtl",
                "--robot-id-check-ms", "0", "--identity", (pki / "service").string()},
               "ignav-server ready"});
  EXPECT_TRUE(good.alive());
}

}  // namespace
}  // namespace ignav::e2e
