// A DDS client of ignav-server: commands with exactly-one replies, slices, and the state topics
// mirrored as values (mirror()) and as their JSON views (state(), json_view.hpp). ignavctl, the web
// gateway and the end-to-end tests are built on it. Includes no DDS: the C types stay in
// protocol/src.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "ignav/protocol/commands.hpp"
#include "ignav/protocol/config.hpp"
#include "ignav/protocol/errors.hpp"
#include "ignav/protocol/json_view.hpp"
#include "ignav/protocol/security.hpp"
#include "ignav/protocol/topics.hpp"
#include "ignav/protocol/types.hpp"

namespace ignav::protocol {

// What a command carries (commands/command_table.hpp says which fields each command takes).
struct CommandArgs {
  std::string path;
  std::vector<Eigen::Vector3d> points;
  std::vector<std::uint32_t> ids;
  std::optional<Eigen::Matrix4d> matrix = std::nullopt;  // set_registration, load_confirmation
};

struct SliceArgs {
  std::string view = "axial";
  Eigen::Vector3d centre_lps = Eigen::Vector3d::Zero();
  std::uint32_t size_px = 512;
  double pixel_mm = 0.0;
  double window = 0.0;
  double level = 0.0;
  bool overlays = true;
  bool region_only = false;  // with overlays: only the feasible region and the structures
};

struct SliceResult {
  bool ok = false;
  std::string message;
  std::uint32_t width = 0, height = 0;
  Eigen::Matrix4d pixel_to_lps = Eigen::Matrix4d::Identity();
  std::vector<std::uint8_t> png;
};

// The state topics as their values: what poll() took last of each (absent: nothing yet), and
// the targets by id (a disposed one removed). state() is the same, as JSON views.
// When to make anew a DDS Security participant that has not matched its server: Cyclone 0.10
// never mends a handshake that lost a message (it resends the same one), while a new participant
// starts a new handshake. The first attempt lasts `first`, each next one twice as long, up to
// `most`. One schedule for every client (Client::waitForServer, discoverRobots, the web gateway,
// net_probe).
class RemakeSchedule {
 public:
  using Clock = std::chrono::steady_clock;
  RemakeSchedule(std::chrono::milliseconds first, std::chrono::milliseconds most)
      : first_(first), most_(most), attempt_(first), end_(Clock::now() + first) {}
  bool due() const { return Clock::now() >= end_; }  // the attempt is over, unmatched
  std::chrono::milliseconds attempt() const { return attempt_; }
  void remade() {  // a new participant: the next attempt, twice as long
    attempt_ = std::min(attempt_ * 2, most_);
    end_ = Clock::now() + attempt_;
  }
  void matched() {  // matched now: a later loss starts again from the first attempt
    attempt_ = first_;
    end_ = Clock::now() + first_;
  }

 private:
  std::chrono::milliseconds first_, most_, attempt_;
  Clock::time_point end_;
};

struct StateMirror {
  std::optional<WorkflowState> workflow;
  std::optional<RobotState> robot;
  std::optional<VolumeState> volume;
  std::optional<RegistrationState> registration;
  std::map<std::uint32_t, TargetState> targets;
  std::optional<ApprovalState> approval;
  std::optional<MotionState> motion;
  std::optional<Health> health;
  std::optional<VerificationState> verification;
  std::optional<StructuresState> structures;
};

// Threads: commands (send, approve, emergencyStop and what waits on them), views (slice, scene)
// and the state (poll, state, takeJobOutcomes) may each run on a thread of its own at once, as
// the web gateway does (a slice being drawn never holds up an emergency stop or the state); each
// of the three on one thread at a time. makeParticipantAnew only with nothing else running.
class Client {
 public:
  // identity: DDS Security on, as that identity (security.hpp); the writers its permissions
  // refuse are missing, and using one throws PermissionDenied naming the topic. robot_id: the
  // robot whose server this client talks to (its DDS partition; chooseRobot finds it).
  Client(std::uint32_t domain_id, const std::string& config_xml, std::string client_id,
         const SecurityIdentity* identity, const std::string& robot_id);
  ~Client();

  // How long a command polls for its reply before it sleeps on the waitset (default 2 ms, which
  // saves the ~150 µs of a wake-up). Many clients on one small machine (tools/bench/bench_load)
  // set 0, so that their polling does not take the cores the server needs.
  void setReplySpin(std::chrono::microseconds spin) { reply_spin_ = spin; }

  // Until the server's command reader and reply writer are matched. With DDS Security, a
  // participant whose handshake lost a message never recovers (Cyclone 0.10 resends the same
  // message): one not matched within a few seconds is made anew, with a doubling wait, until
  // `timeout` (issue 38).
  bool waitForServer(std::chrono::milliseconds timeout);
  int participantsMade() const { return participants_made_; }  // 1 + how often made anew
  // Makes the participant anew (its state mirror starts empty): a long-running client (the web
  // gateway) that stays unmatched under DDS Security calls it with its own backoff.
  void makeParticipantAnew();
  // Sends one command and waits for its reply (throws Timeout). request_id 0: the next one.
  Reply send(const std::string& command, const CommandArgs& args = {},
             std::chrono::milliseconds timeout = std::chrono::seconds(30),
             std::uint64_t request_id = 0);
  // set_registration: a registration computed elsewhere, p_robot = image_to_robot * p_lps.
  Reply setRegistration(const Eigen::Matrix4d& image_to_robot,
                        std::chrono::milliseconds timeout = std::chrono::seconds(30));
  // Approves the pending motion (ApprovalState's plan id and digest) on the approval topic.
  Reply approve(std::uint64_t plan_id, const std::string& digest,
                std::chrono::milliseconds timeout = std::chrono::seconds(30),
                std::uint64_t request_id = 0);
  // On the emergency-stop topic.
  Reply emergencyStop(std::chrono::milliseconds timeout = std::chrono::seconds(30));
  SliceResult slice(const SliceArgs& args,
                    std::chrono::milliseconds timeout = std::chrono::seconds(30));
  // A part of the 3D view's scene (issue 43): `part` "volume" (the slab from `first_slice`; ask
  // again from first_slice + slice_count until dims[2]) or "surfaces". Not ok: message says why.
  SceneReply scene(const std::string& part, std::uint32_t first_slice = 0,
                   std::uint32_t max_voxels_per_axis = 0,
                   std::chrono::milliseconds timeout = std::chrono::seconds(30));

  // Drains the state topics into state(); returns the names of the topics that changed
  // ("workflow", "robot", "volume", "registration", "target", "approval", "motion", "health",
  // "verification").
  std::vector<std::string> poll();
  // Polls until `done(state())` holds (throws Timeout).
  void waitFor(const std::function<bool(const nlohmann::json&)>& done,
               std::chrono::milliseconds timeout);
  // The same on the mirrored values.
  void waitUntil(const std::function<bool(const StateMirror&)>& done,
                 std::chrono::milliseconds timeout);
  // Until the mirror holds the server's present: a sample of every state topic the server
  // publishes from its start, and every target WorkflowState lists. False when it did not arrive
  // within `timeout` (missingState() says what is missing): a one-shot reader must then say "not
  // yet known", not "none".
  bool waitForPresent(std::chrono::milliseconds timeout);
  // What became of the background job a command started (its Reply.job: auto_fiducials,
  // load_confirmation), as the server reports it on the JobOutcome topic: done, failed or stale,
  // with why. Throws Timeout. Outcomes of other jobs that arrive meanwhile are kept for their own
  // wait (the last 64).
  JobOutcome waitForJobOutcome(std::uint64_t job, std::chrono::milliseconds timeout);
  // The outcomes that arrived since last time, whichever job they name (a gateway passes them on);
  // they are kept for waitForJobOutcome too.
  std::vector<JobOutcome> takeJobOutcomes();
  std::vector<std::string> missingState() const;  // the topics (and targets) not yet heard
  const nlohmann::json& state() const { return state_; }
  const StateMirror& mirror() const { return mirror_; }
  // Whether this identity's DDS Security permissions let it publish what `command` travels on (a
  // command name, or "approve"); always true without security. The server still judges it.
  bool mayPublish(const std::string& command) const;
  const std::string& clientId() const { return client_id_; }

 private:
  Reply awaitReply(std::uint64_t request_id, const std::string& what,
                   std::chrono::milliseconds timeout);
  bool serverMatched() const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
  // What the participant was made from, to make it anew (waitForServer).
  std::uint32_t domain_id_;
  std::string config_xml_;
  std::optional<SecurityIdentity> identity_;
  std::string robot_id_;
  int participants_made_ = 1;
  std::string client_id_;
  std::atomic<std::uint64_t> next_request_{0};  // set from the clock (see the constructor)
  std::chrono::microseconds reply_spin_ =
      pollingPaysOff() ? std::chrono::milliseconds(2) : std::chrono::milliseconds(0);
  nlohmann::json state_ = nlohmann::json::object();
  StateMirror mirror_;
};

// The ignav servers on a domain, by their Health (robot id, host, session, version, since when),
// sorted by robot id then start. Waits up to `wait`; less once every Health writer matched has
// been heard from and nothing new has come for 300 ms. Throws PermissionDenied if this identity
// may not read every robot's partition (an identity scoped to one robot names it instead).
std::vector<Health> discoverRobots(std::uint32_t domain_id, const std::string& config_xml,
                                   const SecurityIdentity* identity,
                                   std::chrono::milliseconds wait);
// A DDS participant on the domain, as discovery shows it (`ignavctl doctor`).
struct ParticipantSeen {
  std::string guid;     // its GUID prefix, hex
  std::string name;     // its ENTITY_NAME: "ignav-server robot-1", "ignavctl operator@host", ""
  std::string subject;  // the certificate subject its USER_DATA carries (DDS Security), or ""
};
// Every participant discovered on the domain within `wait`, this one's own left out.
std::vector<ParticipantSeen> discoverParticipants(std::uint32_t domain_id,
                                                  const std::string& config_xml,
                                                  const SecurityIdentity* identity,
                                                  std::chrono::milliseconds wait);

// The robot a client should talk to: `named` if given (checked), else the only one discovered.
// Throws RobotNotChosen naming the domain and the robots found when there are none or several.
std::string chooseRobot(std::uint32_t domain_id, const std::string& config_xml,
                        const SecurityIdentity* identity, const std::string& named,
                        std::chrono::milliseconds wait);

// A 4x4 matrix mirrored in state() as 16 row-major numbers (e.g. image_to_robot).
Eigen::Matrix4d matrixFromState(const nlohmann::json& row_major);

}  // namespace ignav::protocol
