// Crash recovery end to end: a server killed with SIGKILL and started again on the same session
// folder rebuilds exactly the state it had acknowledged.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <fstream>

#include "server_process.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using protocol::CommandArgs;
using namespace std::chrono_literals;

TEST(RecoveryE2E, KilledServerComesBackWithEveryAcknowledgedChange) {
  ServerProcess server(51);
  json before;
  protocol::Reply retried;
  {
    auto c = server.client("e2e-recover");
    ASSERT_TRUE(c->send("load_volume", {"phantom:", {}, {}}).accepted);
    c->waitFor(
        [](const json& s) { return s.contains("volume") && s["volume"]["status"] == "loaded"; },
        60s);
    ASSERT_TRUE(c->send("auto_fiducials").accepted);
    c->waitFor([](const json& s) { return stateText(s, "registration", "status") == "registered"; },
               30s);
    ASSERT_TRUE(c->send("add_target", {"", {lpsOf(c->state(), {8, 12, -175})}, {}}).accepted);
    retried = c->send("add_target", {"", {lpsOf(c->state(), {-10, 15, -190})}, {}}, 10s, 777);
    ASSERT_TRUE(retried.accepted);
    ASSERT_TRUE(c->send("add_target", {"", {lpsOf(c->state(), {40, 0, -180})}, {}}).accepted);
    ASSERT_TRUE(c->send("remove_target", {"", {}, {3}}).accepted);
    c->waitFor([](const json& s) { return s["targets"].size() == 2; }, 5s);
    before = c->state();
  }
  server.crash();
  server.start();

  auto c = server.client("e2e-recover");
  c->waitFor(
      [&](const json& s) {
        // One record more than before the crash: the server's own server_restarted.
        return s.contains("registration") && s["targets"].size() == 2 &&
               s["workflow"]["revision"] == before["workflow"]["revision"].get<int>() + 1;
      },
      30s);
  const json after = c->state();
  EXPECT_EQ(after["workflow"]["phase"], before["workflow"]["phase"]);
  EXPECT_EQ(after["workflow"]["last_event"], "server_restarted");
  EXPECT_EQ(after["registration"]["image_to_robot"], before["registration"]["image_to_robot"]);
  EXPECT_EQ(after["targets"], before["targets"]);  // the same ids, joints, steps, TRE, order

  // A retry of a request acknowledged before the crash is answered, not executed again.
  const auto again = c->send("add_target", {"", {{0, 0, 0}}, {}}, 10s, 777);
  EXPECT_TRUE(again.accepted);
  EXPECT_EQ(again.target_id, retried.target_id);
  // New targets continue the numbering.
  const auto next = c->send("add_target", {"", {lpsOf(after, {5, 10, -170})}, {}}, 10s, 1001);
  EXPECT_EQ(next.target_id, 4u);

  // Offline, ignav-plan re-derives the same session from the journal and checks every record.
  EXPECT_EQ(server.stop(), 0);
  const auto [status, out] = replayVerified(server.sessionDir());
  ASSERT_EQ(status, 0) << out;
  const json replay = json::parse(out);
  EXPECT_TRUE(replay["verified"].get<bool>());
  ASSERT_EQ(replay["targets"].size(), 3u);
  const json& t1 = replay["targets"][0];
  const json& live = after["targets"][std::to_string(t1["id"].get<int>())];
  EXPECT_DOUBLE_EQ(t1["joints"]["z_s_mm"].get<double>(), live["joints"][2].get<double>());
  EXPECT_EQ(t1["steps"], live["steps"]);
}

TEST(RecoveryE2E, CorruptJournalIsRefusedWithTheLine) {
  ServerProcess server(52);
  {
    auto c = server.client("e2e-corrupt");
    ASSERT_TRUE(c->send("stop").accepted);
  }
  EXPECT_EQ(server.stop(), 0);
  {
    std::ofstream j(server.sessionDir() / "journal.jsonl", std::ios::app);
    j << "{this is not json}\n"
      << R"({"v":1,"revision":9,"t":0,"input":"resume","phase":"imaging"})"
      << "\n";
  }
  const std::string cmd = std::string(IGNAV_SERVER_EXE) +
                          " --config " IGNAV_SOURCE_DIR
                          "/configs/server.yaml --domain 52 --session-dir " +
                          server.sessionDir().string() + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  char buf[512];
  while (fgets(buf, sizeof buf, p))
    out += buf;
  const int status = pclose(p);
  EXPECT_EQ(WEXITSTATUS(status), 2) << out;
  EXPECT_NE(out.find("journal.jsonl line 3: not a JSON object"), std::string::npos) << out;
}

// As a service (the Debian package's unit starts the server with no session folder): a server
// killed mid-session and started again continues that session from its journal; one stopped
// cleanly leaves nothing to continue, and the next start makes a new session.
TEST(RecoveryE2E, AServiceRestartedAfterACrashContinuesItsSessionAndACleanStopEndsIt) {
  namespace fs = std::filesystem;
  const fs::path root = fs::temp_directory_path() / ("ignav_service_" + std::to_string(::getpid()));
  fs::remove_all(root);
  fs::create_directories(root);
  // configs/server.yaml, its sessions in `root`, its relative paths made absolute.
  std::ifstream in(IGNAV_SOURCE_DIR "/configs/server.yaml");
  std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"session_root: ../out/sessions", "session_root: " + (root / "sessions").string()},
           {"robot_config: robots/", "robot_config: " IGNAV_SOURCE_DIR "/configs/robots/"},
           {"config: dds/", "config: " IGNAV_SOURCE_DIR "/configs/dds/"},
           {"profiles: tissues.yaml", "profiles: " IGNAV_SOURCE_DIR "/configs/tissues.yaml"},
           {"site: sites/", "site: " IGNAV_SOURCE_DIR "/configs/sites/"}}) {
    const auto at = yaml.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    yaml.replace(at, from.size(), to);
  }
  std::ofstream(root / "server.yaml") << yaml;
  ServerProcess server(
      198, ServerProcess::Program{{IGNAV_SERVER_EXE, "--config", (root / "server.yaml").string(),
                                   "--domain", "198", "--no-igtl", "--robot-id-check-ms", "150"},
                                  "ignav-server ready"});
  std::string session;
  std::uint64_t revision = 0;
  {
    auto c = server.client("operator");
    ASSERT_TRUE(c->send("load_volume", {"phantom:", {}, {}}).accepted);
    c->waitFor([](const json& s) { return stateText(s, "volume", "status") == "loaded"; }, 60s);
    session = c->mirror().workflow->session_id;
    revision = c->mirror().workflow->revision;
  }
  EXPECT_TRUE(fs::exists(root / "sessions" / ".unfinished-robot-1"));
  server.crash();
  server.start();
  {
    auto c = server.client("operator");
    // Every state topic's present, not only the workflow's (it failed once under load, reading a
    // volume topic that had not arrived yet).
    ASSERT_TRUE(c->waitForPresent(10s));
    EXPECT_EQ(c->mirror().workflow->session_id, session);
    EXPECT_GE(c->mirror().workflow->revision, revision);
    EXPECT_EQ(stateText(c->state(), "volume", "status"), "loaded");
  }
  EXPECT_NE(server.serverLog().find("did not end cleanly: continuing it"), std::string::npos);
  EXPECT_EQ(server.stop(), 0);
  EXPECT_FALSE(fs::exists(root / "sessions" / ".unfinished-robot-1"));
  server.start();
  {
    auto c = server.client("operator");
    ASSERT_TRUE(c->waitForPresent(10s));
    EXPECT_NE(c->mirror().workflow->session_id, session);
    EXPECT_EQ(stateText(c->state(), "volume", "status"), "none");
  }
  server.stop();
  fs::remove_all(root);
}

}  // namespace
}  // namespace ignav::e2e
