// Sessions end to end: the server killed at many points of a scripted session comes back with
// everything it acknowledged and moves nothing unapproved; a recorded session replays over DDS
// (`ignavctl replay`) to the same state.
#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "server_process.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using protocol::Client;
using namespace std::chrono_literals;

const std::vector<std::string> kFast = {"--controller-speed", "40000"};

std::vector<json> journalRecords(const std::filesystem::path& session) {
  std::ifstream in(session / "journal.jsonl");
  std::vector<json> out;
  for (std::string line; std::getline(in, line);)
    out.push_back(json::parse(line));
  return out;
}

enum class Drive { kDone, kCrashed, kTimedOut };

// An operator who does whatever the phase needs next until the procedure is done: load the
// phantom, register, click one target, lock, approve every request, reset after a fault, resume
// after a stop. Every accepted request id goes into `acknowledged`.
Drive driveToDone(ServerProcess& server, Client& c, std::vector<std::uint64_t>& acknowledged) {
  const auto end = std::chrono::steady_clock::now() + 60s;
  bool added = false;  // the targets' samples may trail the workflow's: click once
  while (std::chrono::steady_clock::now() < end) {
    if (!server.alive()) return Drive::kCrashed;
    c.poll();
    const json& s = c.state();
    if (!s.contains("workflow")) {
      std::this_thread::sleep_for(5ms);
      continue;
    }
    const std::string phase = s["workflow"]["phase"];
    if (phase == "done") return Drive::kDone;
    std::optional<protocol::Reply> r;
    try {
      if (phase == "imaging" && (!s.contains("volume") || s["volume"]["status"] != "loading")) {
        r = c.send("load_volume", {"phantom:", {}, {}}, 1s);
      } else if (phase == "registration") {
        r = c.send("auto_fiducials", {}, 1s);
      } else if (phase == "planning" && s.contains("registration") &&
                 s["registration"]["status"] == "registered") {
        if (s["targets"].empty() && !added) {
          r = c.send("add_target", {"", {lpsOf(s, {-10, 15, -190})}, {}}, 1s);
          added = r->accepted;
        } else if (!s["targets"].empty()) {
          r = c.send("lock_plan", {}, 1s);
        }
      } else if ((phase == "plan_locked" || phase == "at_target") && s.contains("approval") &&
                 s["approval"]["status"] == "pending") {
        r = c.approve(s["approval"]["plan_id"], s["approval"]["digest"], 1s);
      } else if (phase == "fault" || phase == "emergency") {
        r = c.send("reset_emergency", {}, 1s);
      } else if (phase == "stopped") {
        r = c.send("resume", {}, 1s);
      }
    } catch (const protocol::Timeout&) {
      continue;  // the server died (checked above) or is busy
    }
    if (r && r->accepted) {
      acknowledged.push_back(r->request_id);
      try {
        const auto revision = r->revision;
        c.waitFor(
            [&](const json& st) {
              return st["workflow"]["revision"].get<std::uint64_t>() >= revision;
            },
            3s);
      } catch (const protocol::Timeout&) {
      }
    } else {
      std::this_thread::sleep_for(5ms);
    }
  }
  return Drive::kTimedOut;
}

TEST(SessionE2E, KilledBeforeOrAfterAnyJournalWriteLosesNothingAndMovesNothingUnapproved) {
  // Revisions of the scripted session: 2 load_volume, 3 volume_loaded (the server's own), 4
  // auto_fiducials (the detection starts), 5 fiducials_detected (the server's own: registered), 6
  // add_target, 7 lock_plan, 8 approve, 9 the first move's arrival, and so on. A crash at 5 leaves
  // a detection under way: the restarted server runs it again.
  std::uint32_t domain = 70;
  for (const int revision : {2, 3, 5, 8, 9}) {
    for (const char* where : {"before_journal", "after_journal"}) {
      const std::string crash = std::string(where) + ":" + std::to_string(revision);
      SCOPED_TRACE(crash);
      ServerProcess server(domain++, kFast, {"IGNAV_CRASH_AT=" + crash});
      std::vector<std::uint64_t> acknowledged;
      {
        auto c = server.client("operator");
        ASSERT_EQ(driveToDone(server, *c, acknowledged), Drive::kCrashed) << server.serverLog();
      }
      const auto before = journalRecords(server.sessionDir());
      ASSERT_FALSE(before.empty());
      // The record of the step that crashed is there exactly when the crash came after writing.
      EXPECT_EQ(before.back()["revision"].get<int>(),
                std::string(where) == "after_journal" ? revision : revision - 1);

      server.setEnv({});
      server.start();
      auto c = server.client("operator");
      // The restart is recorded as the next revision. (Not "last_event == server_restarted": a
      // load the crash interrupted finishes after the restart, and a client that joins late sees
      // only the latest state.)
      const auto restarted = before.back()["revision"].get<std::uint64_t>() + 1;
      c->waitFor(
          [&](const json& s) {
            return s.contains("motion") &&
                   s["workflow"]["revision"].get<std::uint64_t>() >= restarted;
          },
          20s);
      // Nothing acknowledged is lost: every accepted request is in the journal.
      std::stringstream text;
      text << std::ifstream(server.sessionDir() / "journal.jsonl").rdbuf();
      EXPECT_NE(text.str().find("\"input\":\"server_restarted\""), std::string::npos);
      for (auto id : acknowledged) {
        EXPECT_NE(text.str().find("\"request_id\":" + std::to_string(id)), std::string::npos)
            << "request " << id << " was acknowledged but is not in the journal";
      }
      // Nothing moves without a new approval.
      EXPECT_NE(c->state()["workflow"]["phase"], "moving");
      const json motion = c->state()["motion"];
      EXPECT_EQ(motion["steps"], motion["verified_steps"]);
      std::this_thread::sleep_for(200ms);
      c->poll();
      EXPECT_EQ(c->state()["motion"]["steps"], motion["steps"]);
      // And the procedure can be finished.
      ASSERT_EQ(driveToDone(server, *c, acknowledged), Drive::kDone) << server.serverLog();
    }
  }
}

TEST(SessionE2E, RecordedSessionReplaysOverDdsToTheSameStates) {
  ServerProcess live(86, kFast);
  json final_state;
  {
    auto c = live.client("operator");
    std::vector<std::uint64_t> acknowledged;
    ASSERT_EQ(driveToDone(live, *c, acknowledged), Drive::kDone);
    c->waitFor([](const json& s) { return stateText(s, "motion", "state") == "idle"; }, 5s);
    final_state = c->state();
  }
  ASSERT_EQ(live.stop(), 0);
  const auto records = journalRecords(live.sessionDir());
  const std::string session = live.sessionDir().string();

  // The whole session, as fast as it goes.
  {
    ServerProcess replay(
        87, ServerProcess::Program{
                {IGNAVCTL_EXE, "--domain", "87", "--dds-config",
                 IGNAV_SOURCE_DIR "/configs/dds/loopback.xml", "replay", session, "--speed", "max",
                 "--server-config", IGNAV_SOURCE_DIR "/configs/server.yaml"},
                "ignav-server replayed"});
    auto c = replay.client("viewer");
    c->waitFor(
        [&](const json& s) {
          return s.contains("registration") && s.contains("motion") &&
                 s["workflow"]["revision"] == records.back()["revision"] &&
                 s["targets"].size() == final_state["targets"].size();
        },
        10s);
    const json& s = c->state();
    EXPECT_EQ(s["workflow"]["phase"], "done");
    EXPECT_EQ(s["registration"]["image_to_robot"], final_state["registration"]["image_to_robot"]);
    EXPECT_EQ(s["targets"], final_state["targets"]);
    EXPECT_EQ(s["motion"]["steps"], final_state["motion"]["steps"]);
    EXPECT_EQ(s["motion"]["verified_steps"], final_state["motion"]["verified_steps"]);
    // Read only: commands are refused; slices of the replayed CT are served.
    const auto refused = c->send("stop", {}, 5s);
    EXPECT_EQ(refused.error_code, "read_only") << refused.message;
    protocol::SliceArgs a;
    a.centre_lps = lpsOf(s, {-10, 15, -190});
    a.size_px = 64;
    EXPECT_TRUE(c->slice(a, 5s).ok);
  }

  // Up to the approval: the replay stops in "moving", at the position the approval started from.
  std::uint64_t approve_revision = 0;
  json approve_reading;
  for (const auto& r : records) {
    if (r["input"] == "approve") {
      approve_revision = r["revision"];
      approve_reading = r["controller"]["position"];
      break;
    }
  }
  ASSERT_GT(approve_revision, 0u);
  ServerProcess replay(
      88, ServerProcess::Program{{IGNAVCTL_EXE, "--domain", "88", "--dds-config",
                                  IGNAV_SOURCE_DIR "/configs/dds/loopback.xml", "replay", session,
                                  "--speed", "max", "--until", std::to_string(approve_revision),
                                  "--server-config", IGNAV_SOURCE_DIR "/configs/server.yaml"},
                                 "ignav-server replayed"});
  auto c = replay.client("viewer");
  c->waitFor(
      [&](const json& s) {
        return s.contains("motion") && s["workflow"]["revision"] == approve_revision;
      },
      10s);
  EXPECT_EQ(c->state()["workflow"]["phase"], "moving");
  EXPECT_EQ(c->state()["motion"]["steps"], approve_reading);
}

}  // namespace
}  // namespace ignav::e2e
