// DDS Security end to end: a real ignav-server with a service identity, clients with the test
// PKI's role identities (configs/security/make-test-pki.sh), real Cyclone DDS on loopback with
// authentication, access control and encryption on. Domains 90-95.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <sstream>
#include <thread>

#include "ignav/protocol/security.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "ignav/volume/phantom.hpp"
#include "server_process.hpp"

namespace ignav::e2e {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using protocol::Client;
using protocol::PermissionDenied;
using protocol::SecurityIdentity;
using namespace std::chrono_literals;

std::string slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Two PKIs made once per test process: ours, and a rogue one with the same role names signed by
// another CA.
const fs::path& pki() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("ignav_pki_" + std::to_string(::getpid()));
    fs::remove_all(d);
    const std::string script = IGNAV_SOURCE_DIR "/configs/security/make-test-pki.sh";
    const std::string ours = script + " " + d.string() + " >/dev/null";
    const std::string rogue =
        script + " " + (d / "rogue").string() + " --ca-name 'rogue CA' >/dev/null";
    if (std::system(ours.c_str()) != 0 || std::system(rogue.c_str()) != 0) {
      ADD_FAILURE() << "make-test-pki.sh failed";
    }
    return d;
  }();
  return dir;
}

SecurityIdentity identity(const std::string& role) {
  return protocol::identityFromFolder((pki() / role).string());
}

std::string subjectOf(const std::string& role) {
  std::string s = slurp(pki() / role / "subject.txt");
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r'))
    s.pop_back();
  return s;
}

std::vector<std::string> secureServerArgs(std::vector<std::string> more = {}) {
  std::vector<std::string> args{"--identity", (pki() / "service").string(), "--controller-speed",
                                "40000"};
  args.insert(args.end(), more.begin(), more.end());
  return args;
}

std::unique_ptr<Client> secureClient(const ServerProcess& server, const std::string& role,
                                     const std::string& client_id) {
  const auto id = identity(role);
  auto c =
      std::make_unique<Client>(server.domain(), loopbackXml(), client_id, &id, server.robotId());
  EXPECT_TRUE(c->waitForServer(15s)) << role;
  c->waitFor([](const json& s) { return s.contains("workflow"); }, 10s);
  return c;
}

// Each journal record as JSON.
std::vector<json> journal(const ServerProcess& server) {
  std::vector<json> out;
  std::ifstream in(server.sessionDir() / "journal.jsonl");
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) out.push_back(json::parse(line));
  }
  return out;
}

const json* record(const std::vector<json>& records, const std::string& input) {
  for (const auto& r : records) {
    if (r["input"] == input) return &r;
  }
  return nullptr;
}

// ignavctl as another process with a role's identity (Cyclone authenticates one identity per
// process): its exit code and everything it printed.
CommandRun ctl(const ServerProcess& server, const std::string& role, const std::string& args) {
  return runCommand(std::string(IGNAVCTL_EXE) + " --domain " + std::to_string(server.domain()) +
                    " --dds-config " IGNAV_SOURCE_DIR "/configs/dds/loopback.xml" +
                    (role.empty() ? "" : " --identity " + (pki() / role).string()) + " " + args);
}

TEST(SecurityE2E, TheWholeWorkflowWorksForTheProperRolesAndTheJournalNamesWhoActed) {
  // The approver list names a certificate subject: the self-declared client id does not matter.
  ServerProcess server(90, secureServerArgs({"--approver", subjectOf("approver")}));
  EXPECT_NE(server.serverLog().find("DDS Security on"), std::string::npos) << server.serverLog();
  auto planner = secureClient(server, "planner", "console-1");

  ASSERT_TRUE(planner->send("load_volume", {"phantom:", {}, {}}).accepted);
  planner->waitFor([](const json& s) { return stateText(s, "volume", "status") == "loaded"; }, 60s);
  ASSERT_TRUE(planner->send("auto_fiducials").accepted);
  planner->waitFor(
      [](const json& s) { return stateText(s, "registration", "status") == "registered"; }, 10s);
  const auto added =
      planner->send("add_target", {"", {lpsOf(planner->state(), {8, 12, -175})}, {}});
  ASSERT_TRUE(added.accepted) << added.message;
  ASSERT_TRUE(planner->send("lock_plan").accepted);
  planner->waitFor([](const json& s) { return stateText(s, "approval", "status") == "pending"; },
                   10s);

  // A viewer (another process) sees the state and gets slices.
  const fs::path png = server.sessionDir().string() + "_viewer.png";
  const auto status = ctl(server, "viewer", "--client-id wall status");
  EXPECT_EQ(status.exit_code, 0) << status.output;
  EXPECT_NE(status.output.find("plan_locked"), std::string::npos) << status.output;
  const auto slice = ctl(server, "viewer", "slice --view axial --size 128 --out " + png.string());
  EXPECT_EQ(slice.exit_code, 0) << slice.output;
  EXPECT_GT(fs::file_size(png), 1000u);
  fs::remove(png);

  // The approver (another process, any client id) releases the motion.
  const auto approved = ctl(server, "approver", "--client-id whoever approve --yes");
  ASSERT_EQ(approved.exit_code, 0) << approved.output;
  planner->waitFor([](const json& s) { return phaseIs(s, "at_target"); }, 30s);

  // Emergency stop: any authenticated participant, the viewer included.
  const auto stopped = ctl(server, "viewer", "emergency-stop");
  EXPECT_EQ(stopped.exit_code, 0) << stopped.output;
  planner->waitFor([](const json& s) { return phaseIs(s, "emergency"); }, 10s);

  // The journal names the authenticated identity and the role topic of every command.
  const auto records = journal(server);
  const json* load = record(records, "load_volume");
  const json* approve = record(records, "approve");
  const json* estop = record(records, "emergency_stop");
  ASSERT_TRUE(load && approve && estop);
  EXPECT_EQ((*load)["identity"], subjectOf("planner"));
  EXPECT_EQ((*load)["role"], "planner");
  EXPECT_EQ((*load)["client_id"], "console-1");
  EXPECT_EQ((*approve)["identity"], subjectOf("approver"));
  EXPECT_EQ((*approve)["role"], "approver");
  EXPECT_EQ((*approve)["client_id"], "whoever");
  EXPECT_EQ((*estop)["identity"], subjectOf("viewer"));
  EXPECT_EQ((*estop)["role"], "any");
  // The report lists the approver by certificate subject.
  EXPECT_NE(slurp(server.sessionDir() / "report.md").find(subjectOf("approver")),
            std::string::npos);
}

TEST(SecurityE2E, PermissionsRefuseTheWritersOfTheWrongRoleAndTheServerTheWrongTopic) {
  // The server's approver list names the planner: DDS Security refuses it all the same.
  ServerProcess server(91, secureServerArgs({"--approver", subjectOf("planner")}));
  auto viewer = secureClient(server, "viewer", "wall-display");
  const auto revision = viewer->state()["workflow"]["revision"];

  // A viewer's planner-command writer and a planner's approval writer are refused by DDS Security
  // itself, when they are created.
  EXPECT_THROW(viewer->send("add_target", {"", {{0, 0, 0}}, {}}), PermissionDenied);
  EXPECT_THROW(viewer->send("load_volume", {"phantom:", {}, {}}), PermissionDenied);
  EXPECT_THROW(viewer->approve(1, std::string(64, '0')), PermissionDenied);
  const auto planner_approves =
      ctl(server, "planner", "approve --plan 1 --digest " + std::string(64, '0'));
  EXPECT_NE(planner_approves.exit_code, 0);
  EXPECT_NE(planner_approves.output.find("do not allow publishing on ignav/approval"),
            std::string::npos)
      << planner_approves.output;
  const auto viewer_adds = ctl(server, "viewer", "targets add 0,0,0");
  EXPECT_NE(viewer_adds.exit_code, 0);
  EXPECT_NE(viewer_adds.output.find("ignav/command/planner"), std::string::npos)
      << viewer_adds.output;

  // Another identity in this process is an error, not a participant that silently never matches.
  const auto planner_id = identity("planner");
  EXPECT_THROW(protocol::Participant(server.domain(), loopbackXml(), &planner_id, server.robotId()),
               protocol::DdsError);

  // A viewer that puts a planner's command on the topic it may use is refused by the server.
  {
    const auto id = identity("viewer");
    protocol::Participant p(server.domain(), loopbackXml(), &id, server.robotId());
    EXPECT_THROW(
        protocol::Writer<ignav_msg_Approval>(p, &ignav_msg_Approval_desc,
                                             protocol::topic::kApproval, protocol::Qos::kRequest),
        PermissionDenied);
    protocol::Writer<ignav_msg_Command> commands(
        p, &ignav_msg_Command_desc, protocol::topic::kCommandViewer, protocol::Qos::kRequest);
    protocol::Reader<ignav_msg_Reply> replies(p, &ignav_msg_Reply_desc, protocol::topic::kReply,
                                              protocol::Qos::kRequest);
    for (int i = 0; i < 1000 && (commands.matched() == 0 || replies.matched() == 0); ++i)
      std::this_thread::sleep_for(10ms);
    ASSERT_GT(commands.matched(), 0u);
    protocol::Command sneaky;
    sneaky.client_id = "sneaky";
    sneaky.request_id = 7;
    sneaky.kind = protocol::commandKindFromName("load_volume").value();
    sneaky.path = "phantom:";
    protocol::Owned<ignav_msg_Command> owned;
    commands.write(protocol::toMsg(sneaky, owned));
    std::string code, message;
    for (int i = 0; i < 1000 && code.empty(); ++i) {
      replies.take([&](const ignav_msg_Reply& r) {
        if (std::string(r.client_id) == "sneaky" && r.request_id == 7) {
          code = r.error_code;
          message = r.message;
        }
      });
      std::this_thread::sleep_for(10ms);
    }
    EXPECT_EQ(code, "not_permitted");
    EXPECT_NE(message.find("planner role"), std::string::npos) << message;
  }
  std::this_thread::sleep_for(100ms);
  viewer->poll();
  EXPECT_EQ(viewer->state()["workflow"]["revision"], revision);
}

TEST(SecurityE2E, AnIdentityFromAnotherCaAndAnUnauthenticatedParticipantSeeNothing) {
  ServerProcess server(92, secureServerArgs());
  {
    // Same role names, another CA: its participant is created (its own CA vouches for it) but
    // never authenticates with the server.
    const auto rogue = protocol::identityFromFolder((pki() / "rogue" / "planner").string());
    Client c(server.domain(), loopbackXml(), "rogue", &rogue, server.robotId());
    EXPECT_FALSE(c.waitForServer(3s));
    c.poll();
    EXPECT_FALSE(c.state().contains("workflow")) << c.state().dump();
  }
  {
    Client c(server.domain(), loopbackXml(), "anonymous", nullptr, server.robotId());
    EXPECT_FALSE(c.waitForServer(3s));
    c.poll();
    EXPECT_FALSE(c.state().contains("workflow")) << c.state().dump();
  }
  // The proper identity still gets in, and nothing happened meanwhile.
  auto viewer = secureClient(server, "viewer", "wall-display");
  EXPECT_EQ(viewer->state()["workflow"]["revision"], 1);
}

TEST(SecurityE2E, AMissingIdentityFileIsNamedAndSecurityOffIsLoud) {
  const fs::path broken =
      fs::temp_directory_path() / ("ignav_broken_id_" + std::to_string(::getpid()));
  fs::remove_all(broken);
  fs::create_directories(broken);
  fs::copy(pki() / "viewer", broken, fs::copy_options::recursive);
  fs::remove(broken / "permissions.p7s");
  try {
    protocol::identityFromFolder(broken.string());
    ADD_FAILURE() << "no error";
  } catch (const protocol::DdsError& e) {
    EXPECT_NE(std::string(e.what()).find("permissions.p7s is missing"), std::string::npos)
        << e.what();
  }
  fs::remove_all(broken);
  ServerProcess insecure(93);
  EXPECT_NE(insecure.serverLog().find("DDS SECURITY IS OFF"), std::string::npos)
      << insecure.serverLog();
}

// tshark on the loopback, restricted to one domain's ports (Cyclone: 7400 + 250 * domain + ...).
class Capture {
 public:
  Capture(std::uint32_t domain, const fs::path& file) : file_(file) {
    const int base = 7400 + 250 * static_cast<int>(domain);
    const std::string filter =
        "udp portrange " + std::to_string(base) + "-" + std::to_string(base + 249);
    fs::remove(file_);
    log_ = file_.string() + ".log";
    std::vector<std::string> args{"/usr/bin/tshark", "-i", "lo", "-f", filter, "-w",
                                  file_.string(),    "-q"};
    std::vector<char*> argv;
    for (auto& a : args)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log_.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
    ok_ = posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) == 0;
    posix_spawn_file_actions_destroy(&actions);
    // Capturing once tshark says so (it starts in ~1 s alone; beside a browser test and builds it
    // took longer than the 5 s this waited before).
    for (int i = 0; ok_ && i < 3000 && slurp(log_).find("Capturing on") == std::string::npos; ++i)
      std::this_thread::sleep_for(10ms);
    ok_ = ok_ && slurp(log_).find("Capturing on") != std::string::npos;
  }
  ~Capture() { stop(); }
  // Stops and returns the capture file's bytes.
  std::string stop() {
    if (pid_ > 0) {
      std::this_thread::sleep_for(300ms);  // the last packets reach the file
      ::kill(pid_, SIGINT);
      ::waitpid(pid_, nullptr, 0);
      pid_ = -1;
    }
    return slurp(file_);
  }
  bool ok() const { return ok_; }
  std::string log() const { return slurp(log_); }

 private:
  fs::path file_;
  std::string log_;
  pid_t pid_ = -1;
  bool ok_ = false;
};

// A DICOM series whose SeriesDescription (published in the volume state) carries `marker`.
fs::path seriesWithMarker(const std::string& marker, const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / (name + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  volume::PhantomSpec spec;
  spec.dims = {32, 32, 16};
  volume::DicomWriteOptions options;
  options.patient_name = marker;
  options.series_description = marker;
  EXPECT_TRUE(writeDicomSeries(volume::makePhantom(spec).value(), dir.string(), options).ok());
  return dir;
}

// Loads the series, fetches a slice and queries: what a planner does, on the wire.
std::string capturedSession(std::uint32_t domain, bool secure, const std::string& marker,
                            std::size_t* packets_bytes) {
  const fs::path series = seriesWithMarker(marker, "ignav_series_" + std::to_string(domain) + "_");
  const fs::path pcap = fs::temp_directory_path() / ("ignav_capture_" + std::to_string(::getpid()) +
                                                     "_" + std::to_string(domain) + ".pcapng");
  Capture capture(domain, pcap);
  if (!capture.ok()) {
    ADD_FAILURE() << "tshark could not capture on lo (root or the wireshark group is needed): "
                  << capture.log();
    return "";
  }
  {
    ServerProcess server(domain, secure ? secureServerArgs() : std::vector<std::string>{});
    std::unique_ptr<Client> planner;
    if (secure) {
      planner = secureClient(server, "planner", "console-1");
    } else {
      planner = server.client("console-1");
    }
    const auto r = planner->send("load_volume", {series.string(), {}, {}});
    EXPECT_TRUE(r.accepted) << r.message;
    planner->waitFor([](const json& s) { return stateText(s, "volume", "status") == "loaded"; },
                     30s);
    EXPECT_NE(planner->state()["volume"].dump().find(marker), std::string::npos)
        << "the marker must be in the volume state for this test to mean anything";
    EXPECT_TRUE(planner->slice({}).ok);
    planner->send("query");
  }
  const std::string bytes = capture.stop();
  *packets_bytes = bytes.size();
  fs::remove_all(series);
  fs::remove(pcap);
  fs::remove(pcap.string() + ".log");
  return bytes;
}

TEST(SecurityE2E, APacketCaptureShowsNoPlaintextOfPatientOrSeriesFields) {
  const std::string marker = "IGNAVSECRET" + std::to_string(::getpid());
  // Control: without security the capture must show the marker, or the test proves nothing.
  std::size_t plain_bytes = 0, secure_bytes = 0;
  const std::string plain = capturedSession(94, false, marker, &plain_bytes);
  EXPECT_NE(plain.find(marker), std::string::npos)
      << "security off: the marker should be on the wire (" << plain_bytes << " bytes captured)";
  const std::string encrypted = capturedSession(95, true, marker, &secure_bytes);
  EXPECT_GT(secure_bytes, 100000u) << "the capture saw too little traffic to judge";
  EXPECT_EQ(encrypted.find(marker), std::string::npos)
      << "security on: the marker is on the wire in plaintext";
  // Nor any state topic's name (discovery is encrypted too).
  EXPECT_EQ(encrypted.find("ignav/state/volume"), std::string::npos);
  EXPECT_NE(plain.find("ignav/state/volume"), std::string::npos);
}

}  // namespace
}  // namespace ignav::e2e
