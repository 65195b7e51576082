// The Server's core: construction, the event loop, crash recovery, replay, and the inputs held
// until a fresh controller reading comes. server_core.hpp says where the rest is.
#include <spdlog/spdlog.h>

#include <array>
#include <chrono>
#include <cmath>
#include <iostream>
#include <random>
#include <thread>
#include <tuple>

#include <unistd.h>

#include "ignav/igtl/brp.hpp"
#include "ignav/protocol/config.hpp"
#include "ignav/workflow/reducer.hpp"
#include "server_core.hpp"

namespace ignav::server {
namespace {

namespace fs = std::filesystem;
using namespace ignav::protocol;
using workflow::Input;
using workflow::InputKind;
using workflow::Session;

// Polling after an event, while commands keep coming (none when confined to one CPU).
const auto kBusyPoll =
    protocol::pollingPaysOff() ? std::chrono::milliseconds(2) : std::chrono::milliseconds(0);

// The controller the options name, as MotionState names it.
std::string controllerName(const ControllerOptions& c) {
  return c.kind == "galil" ? fmt::format("galil {}:{}", c.host, c.port) : "simulated";
}

workflow::ApprovalPolicy approvalPolicy(const ServerOptions& o) {
  workflow::ApprovalPolicy p;
  p.approvers = o.approvers;
  p.expiry_s = o.approval_expiry_s;
  p.speed_steps_s = o.controller.speed_steps_s;
  p.acceleration_steps_s2 = o.controller.acceleration_steps_s2;
  p.limits.max_targets = o.max_targets;
  p.limits.max_total_rotation_rad = o.max_total_rotation_deg * M_PI / 180.0;
  return p;
}

// The identity the server presents, if security is on (server.yaml `security:`).
std::optional<SecurityIdentity> serverIdentity(const SecurityOptions& o) {
  if (o.identity.empty()) {
    spdlog::warn(
        "DDS SECURITY IS OFF: no identity configured (server.yaml security.identity or "
        "--identity). Any process on the network can read patient images and send commands, "
        "approvals included. Use this for local development only (docs/SECURITY.md).");
    return std::nullopt;
  }
  SecurityIdentity id = securityIdentity(o);
  spdlog::info("DDS Security on: identity {} ({})", o.identity,
               certificateSubject(readConfigFile(id.certificate)));
  return id;
}

// A version-4 UUID from the kernel's random source: the session's own identity, which the
// approval digests cover (a folder's name can repeat across hosts and robots).
std::string newSessionUuid() {
  std::random_device random("/dev/urandom");
  std::array<std::uint8_t, 16> b{};
  for (std::size_t i = 0; i < b.size(); i += 4) {
    const std::uint32_t word = random();
    for (std::size_t k = 0; k < 4; ++k)
      b[i + k] = static_cast<std::uint8_t>(word >> (8 * k));
  }
  b[6] = static_cast<std::uint8_t>((b[6] & 0x0f) | 0x40);  // version 4
  b[8] = static_cast<std::uint8_t>((b[8] & 0x3f) | 0x80);  // RFC 4122 variant
  std::string out;
  for (std::size_t i = 0; i < b.size(); ++i) {
    if (i == 4 || i == 6 || i == 8 || i == 10) out += '-';
    out += fmt::format("{:02x}", b[i]);
  }
  return out;
}

std::string hostName() {
  char name[256] = {};
  return ::gethostname(name, sizeof name - 1) == 0 ? std::string(name) : std::string("?");
}

}  // namespace

Server::Server(const ServerOptions& o, std::shared_ptr<const config::Robot> robot,
               fs::path session_dir, std::optional<journal::Journal> journal)
    : options_(o),
      session_dir_(std::move(session_dir)),
      controller_name_(controllerName(o.controller)),
      identity_(serverIdentity(o.security)),
      participant_(o.domain_id, o.dds_config_xml, identity_ ? &*identity_ : nullptr, o.robot_id,
                   "ignav-server " + o.robot_id + "@" + hostName()),
      commands_{{participant_, &ignav_msg_Command_desc, topic::kCommandViewer, Qos::kRequest},
                {participant_, &ignav_msg_Command_desc, topic::kCommandPlanner, Qos::kRequest},
                {participant_, &ignav_msg_Command_desc, topic::kCommandApprover, Qos::kRequest}},
      replies_(participant_),
      slice_requests_(participant_),
      scene_requests_(participant_),
      approvals_(participant_, &ignav_msg_Approval_desc, topic::kApproval, Qos::kRequest),
      emergency_stops_(participant_, &ignav_msg_EmergencyStop_desc, topic::kEmergencyStop,
                       Qos::kRequest),
      robot_peers_(participant_, Qos::kStateOfMany),
      participant_started_(Clock::now()),
      host_(hostName()),
      started_unix_s_(wallS()),
      state_(participant_, controller_name_, session_dir_),
      slices_(participant_),
      waitset_(participant_),
      jobs_([this] { waitset_.trigger(); }, session_dir_),
      reports_(session_dir_),
      journal_(std::move(journal)),
      crash_at_(std::getenv("IGNAV_CRASH_AT") ? std::getenv("IGNAV_CRASH_AT") : "") {
  for (const auto& c : commands_)
    waitset_.attach(c.handle());
  if (identity_) senders_.emplace(participant_, identity_->identity_ca);
  waitset_.attach(slice_requests_.handle());
  waitset_.attach(scene_requests_.handle());
  waitset_.attach(approvals_.handle());
  waitset_.attach(emergency_stops_.handle());
  session_ =
      workflow::newSession(session_dir_.filename().string(), std::move(robot), o.robot_config);
  if (o.openigtlink.enabled) {
    igtl_ = IgtlBridge::start(o.openigtlink, session_dir_, [this] { waitset_.trigger(); });
    if (igtl_) {
      state_.setSafetyNotice(igtl_->safetyNotice());
      igtl_->setSurfaceSource(
          [this](SurfacesDone done) { slices_.surfaces(snapshot(), std::move(done)); });
    }
  }
}

int Server::replay(const std::atomic<bool>& stop, const std::vector<std::string>& lines) {
  if (igtl_) igtl_->setReadOnly();
  if (auto conflict = checkRobotIdAtStart()) {
    spdlog::error("{}", *conflict);
    return 4;
  }
  std::cout << "ignav-server replaying " << session_dir_.string()
            << " domain=" << options_.domain_id << " robot=" << options_.robot_id
            << (igtl_ ? " igtl_port=" + std::to_string(igtl_->port()) : std::string()) << std::endl;
  notifier_.ready(
      fmt::format("replaying {} as robot {}", session_dir_.string(), options_.robot_id));
  // Every state topic from the start (as a live server): the session before its first record.
  state_.publishEverything(session_, readings());
  publishMotion();
  const fs::path journal_path = session_dir_ / "journal.jsonl";
  auto load_ct = [this](const std::string& source) { return reloadCt(source); };
  std::optional<double> previous_t;
  for (std::size_t i = 0; i < lines.size() && !stop.load(); ++i) {
    auto replayed = workflow::replayRecord(session_, lines[i], load_ct,
                                           fmt::format("{} line {}", journal_path.string(), i + 1));
    if (!replayed) {
      spdlog::error("{}", replayed.error().message);
      return 2;
    }
    if (options_.replay_until != 0 && replayed->step.session.revision > options_.replay_until) {
      break;
    }
    const double t = replayed->input.time_s;
    if (options_.replay_speed > 0 && previous_t && t > *previous_t) {
      const auto wait = std::chrono::duration<double>((t - *previous_t) / options_.replay_speed);
      serveReadOnly(Clock::now() + std::chrono::duration_cast<Clock::duration>(wait), stop);
    }
    previous_t = t;
    replaceSession(std::move(replayed->step.session));
    if (replayed->input.controller) last_reading_ = *replayed->input.controller;
    state_.publishEffects(session_, replayed->step.effects, readings());
    if (igtl_) {
      igtl_->onState(session_);
      if (replayed->input.controller) igtl_->onPosition(session_, last_reading_.position);
    }
  }
  spdlog::info("replayed to revision {}, phase {}", session_.revision,
               workflow::toString(session_.phase));
  std::cout << "ignav-server replayed revision=" << session_.revision
            << " phase=" << workflow::toString(session_.phase) << std::endl;
  serveReadOnly(Clock::time_point::max(), stop);
  return 0;
}

int Server::run(const std::atomic<bool>& stop, const std::vector<std::string>& journal_lines) {
  // Announced at once; the session is served at once (queries, planning). The controller waits
  // for the robot-id check (startControllerWhenClear in the loop), and so does every input that
  // would reach it: a robot another server drives is left alone, and this server is ready in a
  // fraction of the check (issue 38).
  publishHealth();
  controller_due_ = participant_started_ + std::chrono::milliseconds(options_.robot_id_check_ms);
  recovering_ = !journal_lines.empty();
  if (!recovering_) {
    Input config_loaded;
    config_loaded.kind = InputKind::kConfigLoaded;
    config_loaded.policy = approvalPolicy(options_);
    config_loaded.tissue = options_.tissue;
    config_loaded.site = options_.site;
    config_loaded.robot_id = options_.robot_id;
    config_loaded.session_uuid = newSessionUuid();
    step(config_loaded);
    // Every state topic from the start, empty ones included: a late joiner can then tell "none"
    // from "not yet heard" (issue 38).
    state_.publishEverything(session_, readings());
  } else {
    if (auto ok = recover(journal_lines); !ok) {
      spdlog::error("{}", ok.error().message);
      return 2;
    }
    // A session is its robot's: another robot's server must not continue it (its approvals and
    // positions are the other robot's). Sessions from before issue 38 name no robot.
    if (!session_.robot_id.empty() && session_.robot_id != options_.robot_id) {
      spdlog::error(
          "{}: this session belongs to robot '{}' and this server is robot '{}' "
          "(server.robot_id): start that robot's server on it, or give this one a new session "
          "folder",
          session_dir_.string(), session_.robot_id, options_.robot_id);
      return 2;
    }
    publishEverything();
  }
  publishMotion();
  publishHealth();  // then once a second
  std::cout << "ignav-server ready domain=" << options_.domain_id << " robot=" << options_.robot_id
            << " session=" << session_dir_.string() << " security=" << (identity_ ? "on" : "OFF")
            << (igtl_ ? " igtl_port=" + std::to_string(igtl_->port()) : std::string()) << std::endl;
  notifier_.ready(fmt::format("robot {} on DDS domain {}, session {}", options_.robot_id,
                              options_.domain_id, session_dir_.string()));
  auto last_health = Clock::now();
  auto last_event = Clock::now() - kBusyPoll;
  while (!stop.load()) {
    notifier_.alive();
    if (controllerPending()) {
      // (robot_id_check_ms 0: no check at start; the one below, once a second, still runs.)
      if (options_.robot_id_check_ms > 0) {
        if (auto conflict = robotIdConflict()) {
          spdlog::error("{}; this one did not touch the controller", *conflict);
          notifier_.stopping();
          return 4;
        }
      }
      if (Clock::now() >= controller_due_) startControllerWhenClear();
    }
    // While commands keep coming, poll instead of sleeping: waking a sleeping thread costs
    // ~150 µs on this kind of VM, more than the command itself (docs/PERFORMANCE.md).
    // The controller component wakes the waitset when it has something: no polling here.
    if (Clock::now() - last_event >= kBusyPoll) {
      waitset_.wait(std::chrono::milliseconds(controllerPending() ? 20 : 200));
    } else {
      std::this_thread::yield();
    }
    std::size_t handled = 0;
    // Emergency stops first: the robot halts before anything else is looked at.
    handled += emergency_stops_.takeFrom(
        [&](const ignav_msg_EmergencyStop& e, dds_instance_handle_t from) {
          step(withSender(toInput(fromMsg(e)), "any", emergency_stops_.handle(), from));
        });
    // OpenIGTLink next: its EMERGENCY is an emergency stop too.
    if (igtl_) {
      igtl_->serve(
          session_, last_reading_.position,
          [this](Input in) {
            // A file the server cannot read is refused before the core sees it, as over DDS.
            if (auto refused = checkPath(in)) {
              igtl_->reply(*refused, session_);
              return;
            }
            step(std::move(in));
          },
          [this] { publishHealth(); }, handled);
    }
    handled +=
        approvals_.takeFrom([&](const ignav_msg_Approval& sample, dds_instance_handle_t from) {
          const protocol::Approval a = fromMsg(sample);
          if (reservedClientId(a.client_id, a.request_id)) return;
          step(withSender(toInput(a), "approver", approvals_.handle(), from));
        });
    // A recovered session's first new record is its restart (a load or a detection the crash
    // interrupted, started again, ends after it).
    if (!(controllerPending() && recovering_)) {
      for (auto& in : jobs_.finished()) {
        ++handled;
        step(std::move(in));
      }
    }
    handled += takeCommands();
    // Slices are drawn on the slices thread, from the session as it is now.
    handled += slice_requests_.take(
        [&](const protocol::SliceRequest& r) { slices_.request(r, snapshot()); });
    handled += scene_requests_.take(
        [&](const protocol::SceneRequest& r) { slices_.request(r, snapshot()); });
    takeControllerEvents();
    releaseHeld();
    if (handled > 0) last_event = Clock::now();
    if (session_.volume_status.status == "loading" && ctLoadProgress() != last_progress_) {
      last_progress_ = ctLoadProgress();
      state_.publishVolume(session_, last_progress_);
    }
    if ((session_.robot_placement.placing != 0 &&
         placementProgress() != last_placement_progress_) ||
        (session_.proposals.proposing != 0 && proposalProgress() != last_proposal_progress_)) {
      last_placement_progress_ = placementProgress();
      last_proposal_progress_ = proposalProgress();
      state_.publishStructures(session_, readings());
    }
    if (Clock::now() - last_health > std::chrono::seconds(1)) {
      publishHealth();
      last_health = Clock::now();
      // Two servers with one robot id met (started together, or a network that was split
      // joined): the later one halts its robot and stops, so that one server acts on commands.
      if (auto conflict = robotIdConflict()) {
        spdlog::error("{}; halting the robot and stopping", *conflict);
        Input halt;
        halt.kind = InputKind::kEmergencyStop;
        halt.client_id = "ignav-server";
        halt.role = "any";
        step(std::move(halt));
        notifier_.stopping();
        return 4;
      }
    }
  }
  notifier_.stopping();
  spdlog::info("shutting down: {} commands accepted, {} rejected", session_.accepted,
               session_.rejected);
  return 0;
}

// The client commands on the three role topics.
std::size_t Server::takeCommands() {
  std::size_t handled = 0;
  for (const Role role : kRoles) {
    const auto& reader = commands_[static_cast<int>(role)];
    handled += reader.takeFrom([&](const ignav_msg_Command& sample, dds_instance_handle_t from) {
      const protocol::Command c = commandOf(sample);
      if (reservedClientId(c.client_id, c.request_id)) return;
      auto in = toInput(c);
      if (!in) {
        spdlog::warn("command kind {} from '{}' (request {}) is not one of ours: refused", c.kind,
                     c.client_id.substr(0, 64), c.request_id);
        sendReply({c.client_id, c.request_id, false,
                   workflow::toString(workflow::ReplyCode::kUnknownCommand),
                   fmt::format("command kind {} is not one of ours (docs/PROTOCOL.md lists "
                               "the kinds)",
                               c.kind),
                   0, session_.revision});
        return;
      }
      // The topic is the role (DDS Security permissions decide who may publish on it); a
      // command above that role is refused whatever the client says it is.
      if (requiredRole(c.kind) > role) {
        sendReply(
            {in->client_id, in->request_id, false, "not_permitted",
             fmt::format("'{}' needs the {} role; it came on {} ({} role)", commandKindName(c.kind),
                         toString(requiredRole(c.kind)), commandTopic(role), toString(role)),
             0, session_.revision});
        return;
      }
      if (auto bad = checkPath(*in)) {
        sendReply(*bad);
        return;
      }
      step(withSender(std::move(*in), toString(role), reader.handle(), from));
    });
  }
  return handled;
}

Expected<workflow::LoadedCt> Server::reloadCt(const std::string& source) {
  Input reloaded = workflow::loadCt(0, source, *session_.robot, {session_dir_, {}});
  if (reloaded.kind != InputKind::kVolumeLoaded) {
    return makeError(ErrorCode::kIo, reloaded.error);
  }
  return reloaded.loaded;
}

// Rebuilds the session by feeding the journal through the same reducer, checking each record's
// revision and phase; nothing is published or journaled again, and no load or marker detection
// pending at the crash is lost (it is started again).
Status Server::recover(const std::vector<std::string>& lines) {
  auto load_ct = [this](const std::string& source) { return reloadCt(source); };
  auto recovered =
      workflow::replayJournal(session_, lines, load_ct, (session_dir_ / "journal.jsonl").string());
  if (!recovered) return recovered.error();
  replaceSession(std::move(recovered).value());
  for (auto& job : workflow::pendingJobs(session_)) {
    spdlog::info("{} #{} was under way: started again", workflow::jobKindSpec(job.kind).name,
                 job.id);
    jobs_.start(std::move(job));
  }
  spdlog::info("recovered {} journal records: revision {}, phase {}, {} targets", lines.size(),
               session_.revision, workflow::toString(session_.phase), session_.targets.size());
  return Ok{};
}

void Server::publishEverything() {
  state_.publishEverything(session_, readings());
  reports_.exports(snapshot());
  reports_.verification(snapshot());
  reports_.report(snapshot());
}

// While replaying: slices are drawn from the replayed CT; commands, approvals and emergency stops
// are refused (nothing here moves a robot).
void Server::serveReadOnly(Clock::time_point until, const std::atomic<bool>& stop) {
  auto last_health = Clock::now();
  auto refuse = [this](const char* client, std::uint64_t request) {
    sendReply({client ? client : "", request, false, "read_only",
               "this server replays a recorded session and takes no commands", 0,
               session_.revision});
  };
  while (!stop.load() && Clock::now() < until) {
    notifier_.alive();
    const auto left = until - Clock::now();
    waitset_.wait(std::chrono::duration_cast<std::chrono::milliseconds>(
        std::min<Clock::duration>(left, std::chrono::milliseconds(50))));
    for (const auto& c : commands_)
      c.take([&](const ignav_msg_Command& cmd) { refuse(cmd.client_id, cmd.request_id); });
    approvals_.take([&](const ignav_msg_Approval& a) { refuse(a.client_id, a.request_id); });
    emergency_stops_.take(
        [&](const ignav_msg_EmergencyStop& e) { refuse(e.client_id, e.request_id); });
    slice_requests_.take([&](const protocol::SliceRequest& r) { slices_.request(r, snapshot()); });
    scene_requests_.take([&](const protocol::SceneRequest& r) { slices_.request(r, snapshot()); });
    std::size_t handled = 0;
    if (igtl_) {
      // The bridge answers; every input it makes is refused.
      igtl_->serve(
          session_, last_reading_.position,
          [&](Input in) { refuse(in.client_id.c_str(), in.request_id); },
          [this] { publishHealth(); }, handled);
    }
    if (Clock::now() - last_health > std::chrono::seconds(1)) {
      publishHealth();
      last_health = Clock::now();
    }
  }
}

// The bridge's client id belongs to the bridge, whether it runs or not: a DDS client claiming it
// is refused (it would otherwise borrow an approval right given to OpenIGTLink, which a session
// keeps in its journaled policy across restarts).
bool Server::reservedClientId(const std::string& client_id, std::uint64_t request_id) {
  if (client_id != igtl::kBridgeClientId) return false;
  replies_.write({client_id, request_id, false, "not_permitted",
                  "client id 'openigtlink' is reserved for the OpenIGTLink bridge", 0,
                  session_.revision});
  spdlog::warn("a DDS client used the reserved client id '{}': refused", client_id);
  return true;
}

// A path the server cannot read is refused before acknowledging (the reducer does no I/O).
std::optional<workflow::Reply> Server::checkPath(const Input& in) const {
  if (!workflow::specOf(in.kind).args.path_is_server_file || in.path == workflow::kPhantomSource ||
      in.path.empty() || in.path.size() > workflow::kMaxPathLength) {
    return std::nullopt;
  }
  std::error_code ec;
  if (fs::exists(in.path, ec)) return std::nullopt;
  return workflow::Reply{in.client_id,
                         in.request_id,
                         false,
                         workflow::toString(workflow::ReplyCode::kBadPath),
                         in.path + ": no such file or folder on the server",
                         0,
                         session_.revision};
}

// Stamps who sent an input: the role of its topic and, with DDS Security on, the certificate
// subject the sender authenticated with (docs/SECURITY.md).
Input Server::withSender(Input in, const char* role, dds_entity_t reader,
                         dds_instance_handle_t from) {
  in.role = role;
  if (senders_) {
    const auto sender = senders_->of(reader, from);
    in.identity = sender.subject;
    if (sender.subject.empty()) {
      spdlog::warn("{} from '{}': sender identity not verified: {}", toString(in.kind),
                   in.client_id, sender.why_not);
    }
  }
  return in;
}

}  // namespace ignav::server
