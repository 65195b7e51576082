#include "server.hpp"

#include "controller_component.hpp"
#include "igtl_listener.hpp"
#include "reports.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <ctime>
#include <deque>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include "ignav/actuation/controller.hpp"
#include "ignav/actuation/galil.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/igtl/brp.hpp"
#include "ignav/journal/journal.hpp"
#include "ignav/protocol/messages.hpp"
#include "ignav/protocol/security.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/load.hpp"
#include "ignav/volume/phantom.hpp"
#include "ignav/volume/render.hpp"
#include "ignav/workflow/reducer.hpp"

namespace ignav::server {
namespace {

namespace fs = std::filesystem;
using namespace ignav::protocol;
using workflow::Input;
using workflow::InputKind;
using workflow::Session;
using Clock = std::chrono::steady_clock;

constexpr const char* kVersion = "0.1.0";
constexpr const char* kPhantomSource = "phantom:";
constexpr auto kBusyPoll = std::chrono::milliseconds(2);

struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The controller the options name, as MotionState names it.
std::string controllerName(const ControllerOptions& c) {
  return c.kind == "galil" ? fmt::format("galil {}:{}", c.host, c.port) : "simulated";
}

// The driver the options name; the controller component runs it (the simulation on the
// component's clock). A recovered session's simulation starts where the journal left the motors.
std::unique_ptr<actuation::MotorController> makeDriver(
    const ControllerOptions& c, const std::optional<actuation::Steps>& place_at) {
  if (c.kind == "galil") {
    actuation::GalilOptions g;
    g.host = c.host;
    g.port = c.port;
    g.timeout_ms = c.timeout_ms;
    g.speed_steps_s = c.speed_steps_s;
    g.acceleration_steps_s2 = c.acceleration_steps_s2;
    return std::make_unique<actuation::GalilController>(g);
  }
  std::array<actuation::SimulatedAxis, 3> axes{};
  for (auto& a : axes) {
    a.speed_steps_s = c.speed_steps_s;
    a.acceleration_steps_s2 = c.acceleration_steps_s2;
  }
  auto sim = std::make_unique<actuation::SimulatedController>(axes);
  if (place_at) (void)sim->placeAt(*place_at);
  return sim;
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

std::string sessionName() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y%m%dT%H%M%SZ", &tm);
  return std::string(buf) + "-" + std::to_string(::getpid());
}

// The volume load runs off the event thread; its result comes back as an input.
class Loader {
 public:
  explicit Loader(WaitSet& waitset) : waitset_(waitset) {}
  ~Loader() {
    if (thread_.joinable()) thread_.join();
  }
  Loader(const Loader&) = delete;
  Loader& operator=(const Loader&) = delete;

  void start(const std::string& source, const config::Robot& robot, const fs::path& session_dir) {
    if (thread_.joinable()) thread_.join();
    thread_ = std::thread([this, source, &robot, session_dir] {
      Input in = load(source, robot, session_dir);
      {
        std::lock_guard<std::mutex> lock(mutex_);
        done_.push_back(std::move(in));
      }
      waitset_.trigger();
    });
  }

  // Files read so far and in all (0 when unknown), updated from the loader thread.
  std::pair<std::size_t, std::size_t> progress() const { return {done_files_, total_files_}; }

  std::vector<Input> finished() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<Input> out(done_.begin(), done_.end());
    done_.clear();
    return out;
  }

  // The load itself: run on the loader thread by start(), or directly for crash recovery.
  Input load(const std::string& source, const config::Robot& robot, const fs::path& session_dir) {
    Input in;
    std::string path = source;
    if (source == kPhantomSource && fs::exists(session_dir / "phantom_ct")) {
      path = (session_dir / "phantom_ct").string();  // recovery: the series written before
    } else if (source == kPhantomSource) {
      // The built-in phantom is written as a real DICOM series into the session and read back
      // like any scan.
      auto rp = registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan);
      if (!rp) return failed(rp.error().message);
      rp->spec.oblique = true;
      rp->spec.noise_sigma_hu = 8.0;
      auto v = volume::makePhantom(rp->spec);
      if (!v) return failed(v.error().message);
      path = (session_dir / "phantom_ct").string();
      auto files = volume::writeDicomSeries(*v, path);
      if (!files) return failed(files.error().message);
    }
    volume::DicomLoadOptions options;
    done_files_ = total_files_ = 0;
    options.progress = [this](const volume::Progress& p) {
      total_files_ = p.total;
      done_files_ = p.done;
      // Wake the event loop about every 5 % so the progress reaches clients.
      if (p.total == 0 || p.done % std::max<std::size_t>(1, p.total / 20) == 0) {
        waitset_.trigger();
      }
    };
    auto loaded = volume::loadVolume(path, options);
    if (!loaded) return failed(loaded.error().message);
    in.kind = InputKind::kVolumeLoaded;
    const auto& g = loaded->volume.geometry;
    in.loaded.source = source;
    in.loaded.description = fmt::format(
        "{} x {} x {} voxels, {:.2f} x {:.2f} x {:.2f} mm, {}", g.dims[0], g.dims[1], g.dims[2],
        g.spacing_mm.x(), g.spacing_mm.y(), g.spacing_mm.z(), loaded->volume.description);
    in.loaded.volume = std::make_shared<const volume::Volume>(std::move(loaded->volume));
    return in;
  }

 private:
  static Input failed(const std::string& why) {
    Input in;
    in.kind = InputKind::kVolumeLoadFailed;
    in.error = why;
    return in;
  }

  WaitSet& waitset_;
  std::atomic<std::size_t> done_files_{0}, total_files_{0};
  std::thread thread_;
  std::mutex mutex_;
  std::deque<Input> done_;
};

// The identity the server presents, if security is on (server.yaml `security:`).
std::optional<SecurityIdentity> serverIdentity(const SecurityOptions& o) {
  if (o.identity.empty()) {
    spdlog::warn(
        "DDS SECURITY IS OFF: no identity configured (server.yaml security.identity or "
        "--identity). Any process on the network can read patient images and send commands, "
        "approvals included. Use this for local development only (docs/SECURITY.md).");
    return std::nullopt;
  }
  SecurityIdentity id = identityFromFolder(o.identity);
  if (!o.plugins.empty()) id.plugin_dir = o.plugins;
  spdlog::info("DDS Security on: identity {} ({})", o.identity,
               certificateSubject(readConfigFile(id.certificate)));
  return id;
}

class Server {
 public:
  // Without a journal the server only replays (nothing is written).
  Server(const ServerOptions& o, std::shared_ptr<const config::Robot> robot, fs::path session_dir,
         std::optional<journal::Journal> journal)
      : options_(o),
        identity_(serverIdentity(o.security)),
        participant_(o.domain_id, o.dds_config.empty() ? "" : readConfigFile(o.dds_config),
                     identity_ ? &*identity_ : nullptr),
        commands_{{participant_, &ignav_msg_Command_desc, topic::kCommandViewer, Qos::kRequest},
                  {participant_, &ignav_msg_Command_desc, topic::kCommandPlanner, Qos::kRequest},
                  {participant_, &ignav_msg_Command_desc, topic::kCommandApprover, Qos::kRequest}},
        replies_(participant_, &ignav_msg_Reply_desc, topic::kReply, Qos::kRequest),
        slice_requests_(participant_, &ignav_msg_SliceRequest_desc, topic::kSliceRequest,
                        Qos::kRequest),
        slice_replies_(participant_, &ignav_msg_SliceReply_desc, topic::kSliceReply, Qos::kRequest),
        workflow_(participant_, &ignav_msg_WorkflowState_desc, topic::kWorkflow, Qos::kState),
        robot_(participant_, &ignav_msg_RobotState_desc, topic::kRobot, Qos::kState),
        volume_(participant_, &ignav_msg_VolumeState_desc, topic::kVolume, Qos::kState),
        registration_(participant_, &ignav_msg_RegistrationState_desc, topic::kRegistration,
                      Qos::kState),
        target_(participant_, &ignav_msg_TargetState_desc, topic::kTarget, Qos::kState),
        health_(participant_, &ignav_msg_Health_desc, topic::kHealth, Qos::kState),
        approvals_(participant_, &ignav_msg_Approval_desc, topic::kApproval, Qos::kRequest),
        emergency_stops_(participant_, &ignav_msg_EmergencyStop_desc, topic::kEmergencyStop,
                         Qos::kRequest),
        approval_(participant_, &ignav_msg_ApprovalState_desc, topic::kApprovalState, Qos::kState),
        motion_(participant_, &ignav_msg_MotionState_desc, topic::kMotion, Qos::kState),
        controller_name_(controllerName(o.controller)),
        waitset_(participant_),
        loader_(waitset_),
        session_dir_(std::move(session_dir)),
        reports_(session_dir_),
        journal_(std::move(journal)),
        started_(Clock::now()) {
    for (const auto& c : commands_)
      waitset_.attach(c.handle());
    if (identity_) senders_.emplace(participant_, identity_->identity_ca);
    waitset_.attach(slice_requests_.handle());
    waitset_.attach(approvals_.handle());
    waitset_.attach(emergency_stops_.handle());
    session_ =
        workflow::newSession(session_dir_.filename().string(), std::move(robot), o.robot_config);
    if (o.openigtlink.enabled) startIgtl();
  }

  // Publishes a recorded session's states one record at a time, at the recorded pace divided by
  // the speed (0: at once), then keeps serving them (and slices) until stopped. It drives no
  // controller and takes no commands.
  int replay(const std::atomic<bool>& stop, const std::vector<std::string>& lines) {
    publishHealth();
    std::cout << "ignav-server replaying " << session_dir_.string()
              << " domain=" << options_.domain_id
              << (igtl_ ? " igtl_port=" + std::to_string(igtl_port_) : std::string()) << std::endl;
    const fs::path journal_path = session_dir_ / "journal.jsonl";
    auto load_ct = [this](const std::string& source) -> Expected<workflow::LoadedCt> {
      Input reloaded = loader_.load(source, *session_.robot, session_dir_);
      if (reloaded.kind != InputKind::kVolumeLoaded) {
        return makeError(ErrorCode::kIo, reloaded.error);
      }
      return reloaded.loaded;
    };
    std::optional<double> previous_t;
    for (std::size_t i = 0; i < lines.size() && !stop.load(); ++i) {
      auto replayed = workflow::replayRecord(
          session_, lines[i], load_ct, fmt::format("{} line {}", journal_path.string(), i + 1));
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
      session_ = std::move(replayed->step.session);
      if (replayed->input.controller) last_reading_ = *replayed->input.controller;
      publishEffects(replayed->step.effects);
      if (bridge_) {
        sendIgtl(bridge_->onState(session_));
        if (replayed->input.controller)
          sendIgtl(bridge_->onPosition(session_, last_reading_.position));
      }
    }
    spdlog::info("replayed to revision {}, phase {}", session_.revision,
                 workflow::toString(session_.phase));
    std::cout << "ignav-server replayed revision=" << session_.revision
              << " phase=" << workflow::toString(session_.phase) << std::endl;
    serveReadOnly(Clock::time_point::max(), stop);
    return 0;
  }

  int run(const std::atomic<bool>& stop, const std::vector<std::string>& journal_lines) {
    if (journal_lines.empty()) {
      // A new session starts with the robot at its home: that position is zero.
      startController(true, std::nullopt);
      Input config_loaded;
      config_loaded.kind = InputKind::kConfigLoaded;
      config_loaded.policy = approvalPolicy(options_);
      config_loaded.tissue = options_.tissue;
      if (!step(config_loaded)) return 3;
    } else {
      if (auto ok = recover(journal_lines); !ok) {
        spdlog::error("{}", ok.error().message);
        return 2;
      }
      // A real controller kept counting while we were down; the simulation is told where the
      // journal last verified the motors (a move in flight at the crash stops where it began).
      startController(false, session_.position);
      publishEverything();
      // Approvals die here, and the position is checked against the controller's.
      Input restarted;
      restarted.kind = InputKind::kServerRestarted;
      if (!step(restarted)) return 3;
    }
    publishMotion();
    publishHealth();  // then once a second
    std::cout << "ignav-server ready domain=" << options_.domain_id
              << " session=" << session_dir_.string() << " security=" << (identity_ ? "on" : "OFF")
              << (igtl_ ? " igtl_port=" + std::to_string(igtl_port_) : std::string()) << std::endl;
    auto last_health = Clock::now();
    auto last_event = Clock::now() - kBusyPoll;
    while (!stop.load()) {
      // While commands keep coming, poll instead of sleeping: waking a sleeping thread costs
      // ~150 µs on this kind of VM, more than the command itself (docs/PERFORMANCE.md).
      // The controller component wakes the waitset when it has something: no polling here.
      if (Clock::now() - last_event >= kBusyPoll) {
        waitset_.wait(std::chrono::milliseconds(200));
      } else {
        std::this_thread::yield();
      }
      std::size_t handled = 0;
      bool failed = false;
      // Emergency stops first: the robot halts before anything else is looked at.
      handled += emergency_stops_.takeFrom(
          [&](const ignav_msg_EmergencyStop& e, dds_instance_handle_t from) {
            if (!failed && !step(withSender(toInput(e), "any", emergency_stops_.handle(), from)))
              failed = true;
          });
      // OpenIGTLink next: its EMERGENCY is an emergency stop too.
      if (!failed && !serveIgtl(false, handled)) failed = true;
      handled += approvals_.takeFrom([&](const ignav_msg_Approval& a, dds_instance_handle_t from) {
        if (failed) return;
        if (reservedClientId(a.client_id, a.request_id)) return;
        if (!step(withSender(toInput(a), "approver", approvals_.handle(), from))) failed = true;
      });
      if (failed) return 3;
      for (auto& in : loader_.finished()) {
        ++handled;
        if (!step(in)) return 3;
      }
      for (const Role role : kRoles) {
        const auto& reader = commands_[static_cast<int>(role)];
        handled += reader.takeFrom([&](const ignav_msg_Command& c, dds_instance_handle_t from) {
          if (failed) return;
          if (reservedClientId(c.client_id, c.request_id)) return;
          auto in = toInput(c);
          if (!in) {
            const std::string client = c.client_id ? c.client_id : "";
            spdlog::warn("command kind {} from '{}' (request {}) is not one of ours: refused",
                         c.kind, client.substr(0, 64), c.request_id);
            sendReply({client, c.request_id, false, "unknown_command",
                       fmt::format("command kind {} is not one of ours (docs/PROTOCOL.md lists "
                                   "the kinds)",
                                   c.kind),
                       0, session_.revision});
            return;
          }
          // The topic is the role (DDS Security permissions decide who may publish on it); a
          // command above that role is refused whatever the client says it is.
          if (requiredRole(c.kind) > role) {
            sendReply({in->client_id, in->request_id, false, "not_permitted",
                       fmt::format("'{}' needs the {} role; it came on {} ({} role)",
                                   commandKindName(c.kind), toString(requiredRole(c.kind)),
                                   commandTopic(role), toString(role)),
                       0, session_.revision});
            return;
          }
          if (auto bad = checkPath(*in)) {
            sendReply(*bad);
            return;
          }
          if (!step(withSender(std::move(*in), toString(role), reader.handle(), from)))
            failed = true;
        });
      }
      if (failed) return 3;
      handled += slice_requests_.take([&](const ignav_msg_SliceRequest& r) { answerSlice(r); });
      if (!takeControllerEvents()) return 3;
      if (!releaseHeld()) return 3;
      if (handled > 0) last_event = Clock::now();
      if (session_.volume_status.status == "loading" && loader_.progress() != last_progress_) {
        last_progress_ = loader_.progress();
        publishVolume();
      }
      if (Clock::now() - last_health > std::chrono::seconds(1)) {
        publishHealth();
        last_health = Clock::now();
      }
    }
    spdlog::info("shutting down: {} commands accepted, {} rejected", session_.accepted,
                 session_.rejected);
    return 0;
  }

 private:
  double now_s() const { return std::chrono::duration<double>(Clock::now() - started_).count(); }
  // Inputs carry wall-clock time (Unix seconds): journal times and approval expiries then mean
  // the same across restarts. The simulation and uptime use the monotonic clock.
  static double wall_s() {
    return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch())
        .count();
  }

  // Rebuilds the session by feeding the journal through the same reducer, checking each
  // record's revision and phase; nothing is published or journaled again, and no load pending
  // at the crash is lost (it is started again).
  Status recover(const std::vector<std::string>& lines) {
    auto load_ct = [this](const std::string& source) -> Expected<workflow::LoadedCt> {
      Input reloaded = loader_.load(source, *session_.robot, session_dir_);
      if (reloaded.kind != InputKind::kVolumeLoaded) {
        return makeError(ErrorCode::kIo, reloaded.error);
      }
      return reloaded.loaded;
    };
    auto recovered = workflow::replayJournal(session_, lines, load_ct,
                                             (session_dir_ / "journal.jsonl").string());
    if (!recovered) return recovered.error();
    session_ = std::move(recovered).value();
    if (session_.volume_status.status == "loading") {
      loader_.start(session_.volume_status.source, *session_.robot, session_dir_);
    }
    spdlog::info("recovered {} journal records: revision {}, phase {}, {} targets", lines.size(),
                 session_.revision, workflow::toString(session_.phase), session_.targets.size());
    return Ok{};
  }

  void publishEverything() {
    publishRobot();
    publishVolume();
    publishRegistration();
    for (const auto& t : session_.targets)
      publishTarget(t.id);
    publishApproval();
    publishWorkflow();
    auto snapshot = std::make_shared<const Session>(session_);
    reports_.exports(snapshot);
    reports_.report(snapshot);
  }

  // Inputs that judge the robot by a controller reading wait (held, in order, with the client
  // commands that come after them) for a reading taken after every command already sent to the
  // controller: the latest one may predate a move or a halt, and a slow controller takes seconds
  // per reading. The event loop goes on meanwhile. Emergency stops, queries and pings never wait;
  // an emergency stop refuses what was held (it came after them and must not be undone by them).
  bool step(Input in) {
    if (in.kind == InputKind::kEmergencyStop) {
      refuseHeld("superseded",
                 "not done: an emergency stop came while this waited for a reading of the "
                 "controller");
      return stepNow(std::move(in));
    }
    // Questions that need no reading (query, ping) never wait behind the held inputs.
    const bool at_once =
        workflow::isQuestion(in.kind) && !workflow::needsControllerReading(in.kind);
    const bool client = workflow::isCommand(in.kind) && !at_once;
    if ((client && !held_.empty()) || waitsForReading(in)) {
      if (held_.empty()) held_since_ = Clock::now();
      held_.push_back(std::move(in));
      if (component_) component_->pollNow();
      return true;
    }
    return stepNow(std::move(in));
  }

  bool waitsForReading(const Input& in) const {
    if (!component_ || in.controller || !workflow::needsControllerReading(in.kind)) return false;
    const auto r = component_->latest();
    return r.status.state != actuation::ControllerState::kDisconnected &&
           r.after_command < last_submitted_;
  }

  // Steps the held inputs whose reading has come; one that waited too long is refused.
  bool releaseHeld() {
    const auto limit = std::chrono::milliseconds(6 * options_.controller.timeout_ms + 1000);
    while (!held_.empty()) {
      if (waitsForReading(held_.front())) {
        if (Clock::now() - held_since_ < limit) return true;
        const Input& late = held_.front();
        sendReply({late.client_id, late.request_id, false, "controller_unavailable",
                   fmt::format("not done: no reading of the controller came within {} ms after "
                               "its last command; try again",
                               limit.count()),
                   0, session_.revision});
        held_.pop_front();
        held_since_ = Clock::now();
        continue;
      }
      Input in = std::move(held_.front());
      held_.pop_front();
      held_since_ = Clock::now();
      if (!stepNow(std::move(in))) return false;
    }
    return true;
  }

  void refuseHeld(const char* code, const std::string& why) {
    for (const auto& in : held_) {
      if (!workflow::isCommand(in.kind)) continue;
      sendReply({in.client_id, in.request_id, false, code, why, 0, session_.revision});
    }
    held_.clear();
  }

  // One input through the reducer, then its effects in the order DESIGN.md requires.
  bool stepNow(Input in) {
    in.time_s = wall_s();
    if (workflow::needsControllerReading(in.kind) && !in.controller) {
      // The component's latest reading: taken after every command sent so far (step() held the
      // input until then), or the last word before the connection went. A move it releases is
      // checked again on a reading taken just before it is sent (ControllerComponent::execute).
      in.controller = latestReading().status;
      // An operator resetting or homing may have just reconnected the cable: try again now.
      if ((in.kind == InputKind::kResetEmergency || in.kind == InputKind::kHome) &&
          in.controller->state == actuation::ControllerState::kDisconnected && component_) {
        component_->reconnectNow();
      }
    }
    workflow::Step s = workflow::reduce(session_, in);
    // Halts before anything else, even the journal (DESIGN.md safety invariant 3): handed to the
    // component's halt thread, which sends them at once (queued moves are dropped).
    for (const auto& c : s.effects.controller) {
      if (c.isHalt()) runController(c, std::nullopt);
    }
    if (!s.effects.journal.empty()) crashPoint("before_journal", s.session.revision);
    if (!s.effects.journal.empty() && !journal_failure_.empty()) {
      refuseUnjournaled(in, s.effects);
      return true;
    }
    for (const auto& line : s.effects.journal) {
      if (auto ok = journal_->append(line); !ok) {
        // Nothing is published or acknowledged that the journal does not hold. The robot is
        // halted (its arrivals could not be recorded) and every later change is refused until
        // a restart recovers from the journal as it stands.
        journal_failure_ = ok.error().message;
        spdlog::critical("{}: halting the robot and refusing every change until restarted",
                         journal_failure_);
        runController(workflow::ControllerCommand::stop(), std::nullopt);
        publishHealth();
        refuseUnjournaled(in, s.effects);
        return true;
      }
    }
    if (!s.effects.journal.empty()) crashPoint("after_journal", s.session.revision);
    const workflow::Phase phase_before = session_.phase;
    session_ = std::move(s.session);
    const auto& e = s.effects;
    if (!e.journal.empty() || !e.replies.empty()) {
      spdlog::info("{} from '{}'{} #{}: {} -> {}", workflow::toString(in.kind), in.client_id,
                   in.identity.empty() ? "" : " (" + in.identity + ")", in.request_id,
                   e.replies.empty() || e.replies.front().accepted
                       ? "accepted"
                       : "rejected (" + e.replies.front().error_code + ")",
                   workflow::toString(session_.phase));
    }
    // Moves and the rest only once the journal holds the approval that released them. A move is
    // sent only if the robot is still at rest where its segment starts.
    for (const auto& c : e.controller) {
      if (!c.isHalt()) {
        runController(c, session_.motion
                             ? std::optional<actuation::Steps>(session_.motion->segment_from)
                             : std::nullopt);
      }
    }
    publishEffects(e);
    for (const auto& r : e.replies)
      sendReply(r);
    // The files for people (Slicer exports, report slices, the report) after the replies, on
    // the reports thread: handed a snapshot of the session, never waited for.
    Reports::Snapshot snapshot;
    auto snap = [&] {
      if (!snapshot) snapshot = std::make_shared<const Session>(session_);
      return snapshot;
    };
    if (in.kind != InputKind::kQuery &&
        (e.registration_changed || !e.targets_changed.empty() || !e.targets_removed.empty())) {
      reports_.exports(snap());
    }
    if (session_.phase != phase_before) {
      if (session_.phase == workflow::Phase::kPlanLocked && in.kind == InputKind::kLockPlan) {
        reports_.slices(snap(), true, 0);
      } else if (session_.phase == workflow::Phase::kAtTarget) {
        const workflow::Target* last = nullptr;  // the target just reached
        for (const auto& t : session_.targets) {
          if (t.reached && (!last || t.reached_s > last->reached_s)) last = &t;
        }
        if (last) reports_.slices(snap(), false, last->id);
      }
    }
    if (!e.journal.empty()) reports_.report(snap());
    if (e.load_volume) loader_.start(*e.load_volume, *session_.robot, session_dir_);
    if (bridge_) sendIgtl(bridge_->onState(session_));
    return true;
  }

  // While replaying: slices are answered from the replayed CT; commands, approvals and emergency
  // stops are refused (nothing here moves a robot).
  void serveReadOnly(Clock::time_point until, const std::atomic<bool>& stop) {
    auto last_health = Clock::now();
    auto refuse = [this](const char* client, std::uint64_t request) {
      sendReply({client ? client : "", request, false, "read_only",
                 "this server replays a recorded session and takes no commands", 0,
                 session_.revision});
    };
    while (!stop.load() && Clock::now() < until) {
      const auto left = until - Clock::now();
      waitset_.wait(std::chrono::duration_cast<std::chrono::milliseconds>(
          std::min<Clock::duration>(left, std::chrono::milliseconds(50))));
      for (const auto& c : commands_)
        c.take([&](const ignav_msg_Command& cmd) { refuse(cmd.client_id, cmd.request_id); });
      approvals_.take([&](const ignav_msg_Approval& a) { refuse(a.client_id, a.request_id); });
      emergency_stops_.take(
          [&](const ignav_msg_EmergencyStop& e) { refuse(e.client_id, e.request_id); });
      slice_requests_.take([&](const ignav_msg_SliceRequest& r) { answerSlice(r); });
      std::size_t handled = 0;
      serveIgtl(true, handled);
      if (Clock::now() - last_health > std::chrono::seconds(1)) {
        publishHealth();
        last_health = Clock::now();
      }
    }
  }

  // OpenIGTLink (docs/OPENIGTLINK.md): the listener's thread does the sockets, the bridge
  // translates, and its inputs go through the reducer like any client's. Never fatal: a bind
  // failure leaves the server running without it.
  void startIgtl() {
    const auto& g = options_.openigtlink;
    IgtlListenerOptions lo;
    lo.address = g.address;
    lo.port = g.port;
    lo.timeout_s = g.timeout_s;
    igtl_ = std::make_unique<IgtlListener>(lo, [this] { waitset_.trigger(); });
    auto port = igtl_->start();
    if (!port) {
      spdlog::error("{}; the server runs without OpenIGTLink", port.error().message);
      igtl_.reset();
      return;
    }
    igtl_port_ = *port;
    // Request ids never repeat across restarts (the core answers a repeated one from the journal).
    bridge_.emplace(igtl::BrpOptions{g.allow_motion_approval},
                    static_cast<std::uint64_t>(wall_s() * 1e6));
    spdlog::info("OpenIGTLink (BRP workphase protocol) listening on {}:{}", g.address, igtl_port_);
    if (g.allow_motion_approval) {
      safety_notice_ = fmt::format(
          "motion approval over OpenIGTLink is ON ({}:{}): OpenIGTLink is unauthenticated, so "
          "whoever can connect there can release motion",
          g.address, igtl_port_);
      spdlog::warn("!!! {} !!!", safety_notice_);
    }
  }

  // Takes what the OpenIGTLink clients sent and runs it; false when a step failed fatally.
  // Read only (replay): the bridge answers, and every input it makes is refused.
  bool serveIgtl(bool read_only, std::size_t& handled) {
    if (!igtl_) return true;
    for (auto& ev : igtl_->take()) {
      ++handled;
      switch (ev.kind) {
        case IgtlEvent::Kind::kConnected:
          sendIgtl(bridge_->onConnected(ev.client, session_));
          publishHealth();
          break;
        case IgtlEvent::Kind::kDisconnected:
          bridge_->onDisconnected(ev.client);
          spdlog::warn("OpenIGTLink client {} ({}) gone: {}", ev.client, ev.peer, ev.error);
          publishHealth();
          break;
        case IgtlEvent::Kind::kBadMessage:
          spdlog::warn("OpenIGTLink client {} ({}): {}", ev.client, ev.peer, ev.error);
          igtl_->send(ev.client,
                      igtl::statusMessage("BAD_MESSAGE", igtl::StatusCode::kUnknownInstruction,
                                          ev.error, "bad_message"));
          break;
        case IgtlEvent::Kind::kMessage:
          // Queries may come many times a second: logged only when debugging.
          spdlog::log(
              ev.message.type.rfind("GET_", 0) == 0 ? spdlog::level::debug : spdlog::level::info,
              "OpenIGTLink client {}: {}({}){}", ev.client, ev.message.type, ev.message.device_name,
              ev.message.text.empty() ? "" : " \"" + ev.message.text.substr(0, 64) + "\"");
          sendIgtl(bridge_->onMessage(ev.client, ev.message, session_, last_reading_.position));
          break;
      }
      // The inputs of one message run before the next message is looked at.
      while (!bridge_inputs_.empty()) {
        Input in = std::move(bridge_inputs_.front());
        bridge_inputs_.pop_front();
        if (read_only) {
          sendReply({in.client_id, in.request_id, false, "read_only",
                     "this server replays a recorded session and takes no commands", 0,
                     session_.revision});
        } else if (!step(std::move(in))) {
          return false;
        }
      }
    }
    return true;
  }

  void sendIgtl(igtl::BrpOutput out) {
    if (!igtl_) return;
    for (const auto& m : out.messages) {
      if (m.client == 0) {
        igtl_->broadcast(m.message);
      } else {
        igtl_->send(m.client, m.message);
      }
    }
    for (auto& in : out.inputs)
      bridge_inputs_.push_back(std::move(in));
  }

  // The bridge's client id belongs to the bridge, whether it runs or not: a DDS client claiming
  // it is refused (it would otherwise borrow an approval right given to OpenIGTLink, which a
  // session keeps in its journaled policy across restarts).
  bool reservedClientId(const char* client_id, std::uint64_t request_id) {
    if (!client_id || std::string(client_id) != igtl::kBridgeClientId) return false;
    OwnedReply owned{
        {client_id, request_id, false, "not_permitted",
         "client id 'openigtlink' is reserved for the OpenIGTLink bridge", 0, session_.revision},
        {}};
    replies_.write(owned.build());
    spdlog::warn("a DDS client used the reserved client id '{}': refused", client_id);
    return true;
  }

  // The state topics a step changed.
  void publishEffects(const workflow::Effects& e) {
    if (e.robot_changed) publishRobot();
    if (e.volume_changed) publishVolume();
    if (e.registration_changed) publishRegistration();
    for (auto id : e.targets_removed)
      disposeTarget(id);
    for (auto id : e.targets_changed)
      publishTarget(id);
    if (e.approval_changed) publishApproval();
    if (e.motion_changed || !e.controller.empty()) publishMotion();
    if (e.workflow_changed) publishWorkflow();
  }

  // Fault injection for the crash tests: IGNAV_CRASH_AT=before_journal:REV or after_journal:REV
  // kills the server (SIGKILL, as a power loss) at that point of the step that makes revision REV.
  void crashPoint(const char* where, std::uint64_t revision) const {
    if (crash_at_.empty()) return;
    if (crash_at_ == std::string(where) + ":" + std::to_string(revision)) {
      spdlog::critical("IGNAV_CRASH_AT={}: killing the server", crash_at_);
      spdlog::default_logger()->flush();
      ::raise(SIGKILL);
    }
  }

  // A path the server cannot read is refused before acknowledging (the reducer does no I/O).
  std::optional<workflow::Reply> checkPath(const Input& in) const {
    if (in.kind != InputKind::kLoadVolume || in.path == kPhantomSource || in.path.empty() ||
        in.path.size() > workflow::kMaxPathLength) {
      return std::nullopt;
    }
    std::error_code ec;
    if (fs::exists(in.path, ec)) return std::nullopt;
    return workflow::Reply{in.client_id,
                           in.request_id,
                           false,
                           "bad_path",
                           in.path + ": no such file or folder on the server",
                           0,
                           session_.revision};
  }

  // An input whose journal record cannot be written: nothing of it happens (but the halts, which
  // ran first) and its sender is told why.
  void refuseUnjournaled(const Input& in, const workflow::Effects& effects) {
    for (const auto& r : effects.replies) {
      sendReply({r.client_id, r.request_id, false, "journal_failed",
                 fmt::format("not done: the session journal cannot be written ({}){}; restart "
                             "the server once the disk is fixed",
                             journal_failure_,
                             in.kind == InputKind::kEmergencyStop ? "; the robot WAS halted" : ""),
                 0, session_.revision});
    }
    // The server's own inputs (a finished move, say) come back every control period: say it once.
    if (effects.replies.empty() && unjournaled_kinds_.insert(in.kind).second) {
      spdlog::error("{} not recorded (journal failed): dropped", workflow::toString(in.kind));
    }
  }

  // Stamps who sent an input: the role of its topic and, with DDS Security on, the certificate
  // subject the sender authenticated with (docs/SECURITY.md).
  Input withSender(Input in, const char* role, dds_entity_t reader, dds_instance_handle_t from) {
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

  void sendReply(const workflow::Reply& r) {
    if (bridge_ && r.client_id == igtl::kBridgeClientId) {
      if (!r.accepted) spdlog::warn("rejected (OpenIGTLink): {}", r.message);
      sendIgtl(bridge_->onReply(r, session_));
      return;
    }
    OwnedReply owned{r, {}};
    replies_.write(owned.build());
    if (!r.accepted) spdlog::warn("rejected: {}", r.message);
  }

  // The controller component: started (and its first connection tried) before the first input.
  // Inputs that need a reading wait for that first attempt, within a bound.
  void startController(bool home, const std::optional<actuation::Steps>& place_at) {
    ControllerComponentOptions co;
    co.name = controller_name_;
    co.active_period = std::chrono::milliseconds(options_.controller.control_period_ms);
    co.home_on_first_connect = home;
    component_ = std::make_unique<ControllerComponent>(makeDriver(options_.controller, place_at),
                                                       co, [this] { waitset_.trigger(); });
    component_->start();
    // Connect, set up (4 replies), home, read (3): each within the driver's timeout.
    const auto bound = std::chrono::milliseconds(10 * options_.controller.timeout_ms + 1000);
    if (!component_->waitForFirstReading(bound)) {
      spdlog::error("controller {}: no answer within {} ms; going on without it", controller_name_,
                    bound.count());
    }
    (void)component_->take();  // the first reading is the latest: nothing to judge yet
    last_reading_ = latestReading().status;
    if (last_reading_.state == actuation::ControllerState::kDisconnected) {
      spdlog::error("controller {}: {}", controller_name_, last_reading_.fault);
    }
  }

  ControllerReading latestReading() const {
    if (component_) return component_->latest();
    ControllerReading r;
    r.status.fault = "no controller";
    return r;
  }

  // A controller command from the reducer, to the component's mailbox. Its failure comes back
  // as an event (takeControllerEvents).
  // The one place a workflow command becomes a motor command. A move goes out only if it is
  // exactly one move of an intact approval (ControllerCommand::releasable); anything else halts
  // the robot and becomes a fault (DESIGN.md safety invariant 1).
  void runController(const workflow::ControllerCommand& c,
                     const std::optional<actuation::Steps>& expect_from) {
    if (!component_) return;
    if (!c.releasable()) {
      spdlog::critical("refused to send a move that is not exactly what was approved");
      last_submitted_ = component_->submit({workflow::ControllerAction::kAbort, {}});
      refused_move_ = "refused to send a move that is not exactly what was approved";
      return;
    }
    const std::uint64_t seq = component_->submit({c.action(), c.increments()}, expect_from);
    last_submitted_ = seq;
    if (c.action() == workflow::ControllerAction::kMove) move_seq_ = seq;
  }

  // What the controller component reported since last time: readings are published (and shown
  // to Slicer), a finished move or a fault becomes the reducer's input.
  bool takeControllerEvents() {
    if (!component_) return true;
    if (!refused_move_.empty()) {
      Input fault;
      fault.kind = InputKind::kControllerFault;
      fault.controller = component_->latest().status;
      fault.controller->state = actuation::ControllerState::kFault;
      fault.controller->fault = std::exchange(refused_move_, std::string());
      if (!step(fault)) return false;
    }
    for (auto& ev : component_->take()) {
      if (ev.kind == ControllerEvent::Kind::kCommandFailed) {
        // A command that failed: a controller_fault input. The reducer answers a fault with a
        // halt; a halt that fails for the reason just reported (the controller is gone) must not
        // report it again, or the two feed each other without end (docs/RELIABILITY.md, R1).
        Input fault;
        fault.kind = InputKind::kControllerFault;
        fault.controller = ev.reading.status;
        fault.controller->fault = ev.why;
        if (fault.controller->state == actuation::ControllerState::kIdle ||
            fault.controller->state == actuation::ControllerState::kMoving) {
          fault.controller->state = actuation::ControllerState::kFault;
        }
        if (fault.controller->fault == last_fault_reported_) continue;
        last_fault_reported_ = fault.controller->fault;
        if (!step(std::move(fault))) return false;
        continue;
      }
      if (!onReading(ev.reading)) return false;
    }
    return true;
  }

  bool onReading(const ControllerReading& reading) {
    const auto before = last_reading_;
    const auto& r = reading.status;
    last_reading_ = r;
    const bool changed =
        r.state != before.state || r.position != before.position || r.fault != before.fault;
    if (changed) publishMotion();
    // Slicer sees the tip move (at most every 50 ms, and where it comes to rest).
    const bool moving = r.state == actuation::ControllerState::kMoving;
    if (bridge_ && igtl_->clientCount() > 0 && r.position != last_igtl_steps_ &&
        (moving || before.state == actuation::ControllerState::kMoving) &&
        (!moving || Clock::now() - last_igtl_position_ >= std::chrono::milliseconds(50))) {
      last_igtl_position_ = Clock::now();
      last_igtl_steps_ = r.position;
      sendIgtl(bridge_->onPosition(session_, r.position));
    }
    const bool bad = r.state == actuation::ControllerState::kDisconnected ||
                     r.state == actuation::ControllerState::kFault;
    // A segment is done on a reading taken after its move was sent, at rest (or on a fault).
    if (session_.phase == workflow::Phase::kMoving && session_.motion && !moving &&
        (bad || reading.after_command >= move_seq_)) {
      if (bad) last_fault_reported_ = r.fault;
      Input done;
      done.kind = InputKind::kSegmentDone;
      done.controller = r;
      return step(std::move(done));
    }
    if (!bad) {
      last_fault_reported_.clear();
      return true;
    }
    if (r.fault == last_fault_reported_) return true;
    last_fault_reported_ = r.fault;
    Input fault;
    fault.kind = InputKind::kControllerFault;
    fault.controller = r;
    return step(std::move(fault));
  }

  void publishApproval() {
    const std::string none = "none", pending = "pending", empty;
    ignav_msg_ApprovalState a{};
    std::vector<ignav_msg_PlannedMove> moves;
    std::vector<std::string> kinds;
    std::vector<char*> approvers;
    for (const auto& id : session_.policy.approvers)
      approvers.push_back(cstr(id));
    viewSequence(a.approvers, approvers);
    a.status = cstr(none);
    a.digest = a.summary = cstr(empty);
    if (const auto& p = session_.pending) {
      a.status = cstr(pending);
      a.plan_id = p->plan_id;
      a.digest = cstr(p->digest);
      a.target_id = p->target_id;
      a.summary = cstr(p->summary);
      for (int m = 0; m < 3; ++m)
        a.from_steps[m] = p->from.motor[static_cast<std::size_t>(m)];
      kinds.reserve(p->moves.size());
      for (const auto& move : p->moves) {
        kinds.emplace_back(planning::toString(move.kind));
        ignav_msg_PlannedMove pm{};
        pm.kind = cstr(kinds.back());
        for (int m = 0; m < 3; ++m)
          pm.steps[m] = move.steps.motor[static_cast<std::size_t>(m)];
        pm.duration_s = move.duration_s;
        moves.push_back(pm);
      }
      a.duration_s = p->duration_s;
      a.tre_mm = p->tre_mm;
      a.expires_at_unix_s = p->expires_s;
      a.expires_in_s = p->expires_s - wall_s();
    }
    viewSequence(a.moves, moves);
    approval_.write(a);
  }

  void publishMotion() {
    const auto& r = last_reading_;
    const std::string state = actuation::toString(r.state);
    const std::string fault = !session_.fault.empty() ? session_.fault : r.fault;
    std::string kind;
    ignav_msg_MotionState m{};
    m.controller = cstr(controller_name_);
    m.state = cstr(state);
    m.fault = cstr(fault);
    for (std::size_t a = 0; a < 3; ++a) {
      m.steps[a] = r.position.motor[a];
      m.verified_steps[a] = session_.position.motor[a];
      m.goal_steps[a] = session_.position.motor[a];
    }
    if (const auto& mo = session_.motion) {
      const auto& move = mo->request().moves[std::min(mo->segment, mo->request().moves.size() - 1)];
      m.plan_id = mo->request().plan_id;
      m.target_id = mo->request().target_id;
      m.move_index = static_cast<std::uint32_t>(mo->segment + 1);
      m.move_count = static_cast<std::uint32_t>(mo->request().moves.size());
      kind = planning::toString(move.kind);
      for (std::size_t a = 0; a < 3; ++a)
        m.goal_steps[a] = mo->segment_from.motor[a] + move.steps.motor[a];
    }
    m.move_kind = cstr(kind);
    const auto& robot = *session_.robot;
    const auto joints = robot.transmission.toJoints(r.position);
    m.theta_c_rad = joints.theta_c_rad;
    m.z_c_mm = joints.z_c_mm;
    m.z_s_mm = joints.z_s_mm;
    const Eigen::Vector3d tip = robot.kinematics.forward(joints).tip_mm;
    m.tip_robot = toMsg(tip);
    if (session_.registration) {
      m.tip_lps = toMsg(session_.registration->toImage(tip));
      m.tip_lps_valid = true;
    }
    m.uptime_s = now_s();
    motion_.write(m);
  }

  void publishWorkflow() {
    const auto allowed = workflow::allowedCommands(session_.phase);
    std::vector<char*> names;
    for (auto k : allowed)
      names.push_back(const_cast<char*>(workflow::toString(k)));
    const std::string phase = workflow::toString(session_.phase);
    ignav_msg_WorkflowState w{};
    w.session_id = cstr(session_.session_id);
    w.phase = cstr(phase);
    viewSequence(w.allowed_commands, names);
    w.revision = session_.revision;
    w.last_event = cstr(session_.last_event);
    w.safety_notice = cstr(safety_notice_);
    workflow_.write(w);
  }

  void publishRobot() {
    const auto& robot = *session_.robot;
    const auto ws = robot.kinematics.workspace();
    auto features = toMsgs(robot.feature_points_mm);
    ignav_msg_RobotState r{};
    r.name = cstr(robot.config.name);
    r.config_path = cstr(session_.robot_path);
    r.r_min_mm = ws.r_min_mm;
    r.r_max_mm = ws.r_max_mm;
    r.cannula_travel_mm = robot.config.instrument.cannula_travel_mm;
    r.stylet_travel_mm = robot.config.instrument.stylet_travel_mm;
    r.feasible_volume_cm3 = ws.volume_exact_cm3;
    const std::string tissue =
        session_.tissue ? session_.tissue->name + " (λ1 " +
                              fmt::format("{:g}", session_.tissue->tissue.lambda1) + ", λ2 " +
                              fmt::format("{:g}", session_.tissue->tissue.lambda2) + ")"
                        : std::string();
    r.tissue = cstr(tissue);
    viewSequence(r.feature_points_robot, features);
    robot_.write(r);
  }

  void publishVolume() {
    const auto& st = session_.volume_status;
    ignav_msg_VolumeState v{};
    v.status = cstr(st.status);
    v.source = cstr(st.source);
    v.message = cstr(st.message);
    if (const auto& vol = session_.ct.volume) {
      const auto& g = vol->geometry;
      for (int a = 0; a < 3; ++a) {
        v.dims[a] = static_cast<std::uint32_t>(g.dims[a]);
        v.spacing_mm[a] = g.spacing_mm[a];
      }
      toRowMajor(g.ijkToLps(), v.ijk_to_lps);
      if (hu_range_for_ != vol.get()) {
        hu_range_ = vol->valueRange();
        hu_range_for_ = vol.get();
      }
      v.hu_min = hu_range_.first;
      v.hu_max = hu_range_.second;
    }
    if (st.status == "loading") {
      v.progress_done = loader_.progress().first;
      v.progress_total = loader_.progress().second;
    }
    volume_.write(v);
  }

  void publishRegistration() {
    const auto& st = session_.registration_status;
    ignav_msg_RegistrationState r{};
    r.status = cstr(st.status);
    r.message = cstr(st.message);
    r.auto_detected = st.auto_detected;
    std::vector<ignav_msg_Point3> image, robot;
    std::vector<double> residuals;
    std::string kind;
    if (const auto& reg = session_.registration) {
      kind = registration::toString(reg->kind);
      image = toMsgs(reg->image_mm);
      robot = toMsgs(reg->robot_mm);
      residuals = reg->residuals_mm;
      toRowMajor(reg->imageToRobot(), r.image_to_robot);
      r.scale = reg->scale;
      r.fre_mm = reg->fre_mm;
    }
    r.kind = cstr(kind);
    viewSequence(r.image_points, image);
    viewSequence(r.robot_points, robot);
    viewSequence(r.residuals_mm, residuals);
    registration_.write(r);
  }

  void publishTarget(std::uint32_t id) {
    for (std::size_t i = 0; i < session_.targets.size(); ++i) {
      const auto& t = session_.targets[i];
      if (t.id != id) continue;
      // Named, not temporaries: the sample points into them until it is written (ASan found a
      // `cond ? reach : std::string()` that died first).
      const std::string reach = t.registered ? kinematics::toString(t.solution.reach) : "";
      const std::string status = t.status();
      ignav_msg_TargetState m{};
      m.id = t.id;
      m.lps = toMsg(t.lps_mm);
      m.robot = toMsg(t.robot_mm);
      m.registered = t.registered;
      m.reachable = t.registered && t.solution.reachable();
      m.reach = cstr(reach);
      m.message = cstr(t.message);
      m.theta_c_rad = t.solution.joints.theta_c_rad;
      m.z_c_mm = t.solution.joints.z_c_mm;
      m.z_s_mm = t.solution.joints.z_s_mm;
      for (int a = 0; a < 3; ++a)
        m.steps[a] = t.steps.motor[static_cast<std::size_t>(a)];
      m.tre_mm = t.tre_mm;
      m.tre_warning = t.tre_warning;
      m.order = static_cast<std::uint32_t>(i + 1);
      m.deviation_predicted = std::isfinite(t.predicted_deviation_mm);
      m.predicted_deviation_mm = m.deviation_predicted ? t.predicted_deviation_mm : 0.0;
      m.status = cstr(status);
      m.outside_volume = t.outside_volume;
      m.path_warning = cstr(t.path_warning);
      std::vector<ignav_msg_Point3> path;
      if (m.reachable) path = toMsgs(workflow::needlePathLps(session_, t.solution.joints));
      viewSequence(m.path_lps, path);
      target_.write(m);
      return;
    }
  }

  void disposeTarget(std::uint32_t id) {
    ignav_msg_TargetState m{};
    m.id = id;
    const std::string empty;
    m.reach = m.message = m.status = cstr(empty);
    target_.dispose(m);
  }

  void publishHealth() {
    const std::string version = kVersion;
    const std::string dir = session_dir_.string();
    ignav_msg_Health h{};
    h.version = cstr(version);
    h.session_id = cstr(session_.session_id);
    h.session_dir = cstr(dir);
    h.uptime_s = now_s();
    h.commands_accepted = session_.accepted;
    h.commands_rejected = session_.rejected;
    const std::string journal = journal_failure_.empty() ? "ok" : journal_failure_;
    h.journal = cstr(journal);
    h.igtl_clients = igtl_ ? static_cast<std::uint32_t>(igtl_->clientCount()) : 0;
    h.server_time_unix_s = wall_s();
    health_.write(h);
  }

  void answerSlice(const ignav_msg_SliceRequest& req) {
    SliceResultOwned out;
    out.client_id = req.client_id ? req.client_id : "";
    out.request_id = req.request_id;
    auto fail = [&](const std::string& why) {
      out.message = why;
      sendSlice(out);
    };
    if (!session_.ct.volume) return fail("no CT is loaded");
    const std::string view = req.view ? req.view : "";
    volume::SliceSpec spec;
    if (view == "axial") {
      spec.view = volume::View::kAxial;
    } else if (view == "coronal") {
      spec.view = volume::View::kCoronal;
    } else if (view == "sagittal") {
      spec.view = volume::View::kSagittal;
    } else {
      return fail("view '" + view + "' is not axial, coronal or sagittal");
    }
    const Eigen::Vector3d centre = fromMsg(req.centre_lps);
    if (!centre.allFinite() || !std::isfinite(req.pixel_mm) || !std::isfinite(req.window) ||
        !std::isfinite(req.level)) {
      return fail("centre_lps, pixel_mm, window and level must be finite");
    }
    if (req.size_px > 2048) return fail(fmt::format("size_px {} exceeds 2048", req.size_px));
    spec.centre_lps_mm = centre;
    spec.width_px = spec.height_px = static_cast<int>(req.size_px);
    spec.pixel_size_mm = req.pixel_mm;
    spec.window = volume::kWindowBone;
    if (req.window > 0.0) spec.window = {req.window, req.level};
    auto slice = volume::reslice(*session_.ct.volume, spec);
    if (!slice) return fail(slice.error().message);
    volume::Overlays overlays;
    if (req.overlays) overlays = overlaysFor(session_);
    if (req.overlays && req.region_only) {
      overlays.points.clear();
      overlays.paths.clear();
    }
    auto png = volume::renderPng(*slice, overlays);
    if (!png) return fail(png.error().message);
    out.ok = true;
    out.width = static_cast<std::uint32_t>(slice->width);
    out.height = static_cast<std::uint32_t>(slice->height);
    out.pixel_to_lps = slice->pixel_to_lps;
    out.png = std::move(png).value();
    sendSlice(out);
  }

  struct SliceResultOwned {
    std::string client_id, message;
    std::uint64_t request_id = 0;
    bool ok = false;
    std::uint32_t width = 0, height = 0;
    Eigen::Matrix4d pixel_to_lps = Eigen::Matrix4d::Identity();
    std::vector<std::uint8_t> png;
  };

  void sendSlice(SliceResultOwned& s) {
    ignav_msg_SliceReply r{};
    r.client_id = cstr(s.client_id);
    r.request_id = s.request_id;
    r.ok = s.ok;
    r.message = cstr(s.message);
    r.width = s.width;
    r.height = s.height;
    toRowMajor(s.pixel_to_lps, r.pixel_to_lps);
    viewSequence(r.png, s.png);
    slice_replies_.write(r);
  }

  ServerOptions options_;
  std::optional<SecurityIdentity> identity_;  // DDS Security on with it
  Participant participant_;
  Reader<ignav_msg_Command> commands_[3];  // by Role
  Writer<ignav_msg_Reply> replies_;
  Reader<ignav_msg_SliceRequest> slice_requests_;
  Writer<ignav_msg_SliceReply> slice_replies_;
  Writer<ignav_msg_WorkflowState> workflow_;
  Writer<ignav_msg_RobotState> robot_;
  Writer<ignav_msg_VolumeState> volume_;
  Writer<ignav_msg_RegistrationState> registration_;
  Writer<ignav_msg_TargetState> target_;
  Writer<ignav_msg_Health> health_;
  Reader<ignav_msg_Approval> approvals_;
  Reader<ignav_msg_EmergencyStop> emergency_stops_;
  Writer<ignav_msg_ApprovalState> approval_;
  Writer<ignav_msg_MotionState> motion_;
  std::optional<SenderIdentities> senders_;  // with DDS Security on
  std::string journal_failure_;              // why the journal cannot be written ("" = it can)
  std::set<InputKind> unjournaled_kinds_;
  std::string controller_name_;
  actuation::ControllerStatus last_reading_;  // the component's, as last taken (or replayed)
  std::uint64_t move_seq_ = 0;                // the component's number of the last move sent
  std::uint64_t last_submitted_ = 0;          // ... of the last command of any kind
  std::deque<Input> held_;                    // inputs waiting for a fresh reading (step())
  Clock::time_point held_since_;
  std::string last_fault_reported_;
  std::string refused_move_;  // a move runController would not send: a fault, reported next
  WaitSet waitset_;
  Loader loader_;
  // The controller component (run() only; its threads wake the waitset, so it goes first).
  std::unique_ptr<ControllerComponent> component_;
  fs::path session_dir_;
  // The report and the Slicer files, on a thread of their own; drained when the server goes.
  Reports reports_;
  std::optional<journal::Journal> journal_;
  std::string crash_at_ = std::getenv("IGNAV_CRASH_AT") ? std::getenv("IGNAV_CRASH_AT") : "";
  Session session_;
  Clock::time_point started_;
  std::pair<std::size_t, std::size_t> last_progress_{0, 0};
  const volume::Volume* hu_range_for_ = nullptr;
  std::pair<double, double> hu_range_{0.0, 0.0};
  // The OpenIGTLink bridge (last: its thread stops before the waitset it wakes goes away).
  std::optional<igtl::BrpBridge> bridge_;
  std::deque<Input> bridge_inputs_;  // the bridge's inputs, run in order after its message
  std::string safety_notice_;        // a weakened safeguard, said in WorkflowState
  Clock::time_point last_igtl_position_;
  actuation::Steps last_igtl_steps_;
  int igtl_port_ = 0;
  std::unique_ptr<IgtlListener> igtl_;
};

std::string resolve(const fs::path& base, const std::string& p) {
  if (p.empty() || fs::path(p).is_absolute()) return p;
  return (base / p).lexically_normal().string();
}

}  // namespace

std::optional<std::string> checkControllerOptions(const ServerOptions& o) {
  const auto& c = o.controller;
  if (c.kind != "simulated" && c.kind != "galil") {
    return "controller.kind: '" + c.kind + "' is not simulated or galil";
  }
  if (c.port <= 0 || c.port > 65535) {
    return fmt::format("controller.port: {} is not a TCP port", c.port);
  }
  if (!(c.speed_steps_s > 0) || !std::isfinite(c.speed_steps_s)) {
    return fmt::format("controller.speed_steps_s: {} must be positive", c.speed_steps_s);
  }
  if (!(c.acceleration_steps_s2 > 0) || !std::isfinite(c.acceleration_steps_s2)) {
    return fmt::format("controller.acceleration_steps_s2: {} must be positive",
                       c.acceleration_steps_s2);
  }
  if (c.timeout_ms < 10 || c.timeout_ms > 60000) {
    return fmt::format("controller.timeout_ms: {} is not within 10..60000", c.timeout_ms);
  }
  if (c.control_period_ms < 1 || c.control_period_ms > 1000) {
    return fmt::format("controller.control_period_ms: {} is not within 1..1000",
                       c.control_period_ms);
  }
  if (o.max_targets < 1 || o.max_targets > workflow::kMaxTargets) {
    return fmt::format("planning.max_targets: {} is not within 1..{}", o.max_targets,
                       workflow::kMaxTargets);
  }
  if (!(o.max_total_rotation_deg > 0) || o.max_total_rotation_deg > 360.0) {
    return fmt::format("planning.max_total_rotation_deg: {} is not within (0, 360]",
                       o.max_total_rotation_deg);
  }
  const auto& g = o.openigtlink;
  if (g.port < 0 || g.port > 65535) {
    return fmt::format("openigtlink.port: {} is not a TCP port (0..65535; 0 = any)", g.port);
  }
  if (!(g.timeout_s >= 0.5) || g.timeout_s > 3600.0) {
    return fmt::format("openigtlink.timeout_s: {} s; must be within 0.5..3600", g.timeout_s);
  }
  if (!(o.approval_expiry_s > 0) || !std::isfinite(o.approval_expiry_s)) {
    return fmt::format("approval.expiry_s: {} must be positive", o.approval_expiry_s);
  }
  return std::nullopt;
}

ServerOptions loadServerOptions(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw ConfigError(path + ": " + e.what());
  }
  const fs::path base = fs::path(path).parent_path();
  ServerOptions o;
  const YAML::Node s = root["server"];
  if (!s || !s.IsMap()) throw ConfigError(path + ": server: is missing");
  for (const auto& kv : s) {
    const std::string key = kv.first.Scalar();
    if (key != "robot_config" && key != "dds" && key != "session_root" && key != "controller" &&
        key != "approval" && key != "planning" && key != "tissue" && key != "security" &&
        key != "openigtlink") {
      throw ConfigError(path + ": server." + key +
                        ": unknown key; expected robot_config, dds, session_root, controller, "
                        "approval, planning, tissue, security, openigtlink");
    }
  }
  try {
    o.robot_config = resolve(base, s["robot_config"].as<std::string>());
    if (s["session_root"]) o.session_root = resolve(base, s["session_root"].as<std::string>());
    if (const YAML::Node d = s["dds"]) {
      if (d["domain_id"]) o.domain_id = d["domain_id"].as<std::uint32_t>();
      if (d["config"]) o.dds_config = resolve(base, d["config"].as<std::string>());
    }
    if (const YAML::Node c = s["controller"]) {
      auto& co = o.controller;
      for (const auto& kv : c) {
        const std::string key = kv.first.Scalar();
        if (key == "kind") {
          co.kind = kv.second.as<std::string>();
        } else if (key == "host") {
          co.host = kv.second.as<std::string>();
        } else if (key == "port") {
          co.port = kv.second.as<int>();
        } else if (key == "speed_steps_s") {
          co.speed_steps_s = kv.second.as<double>();
        } else if (key == "acceleration_steps_s2") {
          co.acceleration_steps_s2 = kv.second.as<double>();
        } else if (key == "control_period_ms") {
          co.control_period_ms = kv.second.as<int>();
        } else if (key == "timeout_ms") {
          co.timeout_ms = kv.second.as<int>();
        } else {
          throw ConfigError(path + ": server.controller." + key +
                            ": unknown key; expected kind, host, port, speed_steps_s, "
                            "acceleration_steps_s2, control_period_ms, timeout_ms");
        }
      }
    }
    if (const YAML::Node t = s["tissue"]) {
      for (const auto& kv : t) {
        const std::string key = kv.first.Scalar();
        if (key == "profiles") {
          o.tissue_profiles = resolve(base, kv.second.as<std::string>());
        } else if (key == "name") {
          o.tissue_name = kv.second.as<std::string>();
        } else {
          throw ConfigError(path + ": server.tissue." + key +
                            ": unknown key; expected profiles, name");
        }
      }
    }
    if (const YAML::Node pl = s["planning"]) {
      for (const auto& kv : pl) {
        const std::string key = kv.first.Scalar();
        if (key == "max_targets") {
          o.max_targets = kv.second.as<std::size_t>();
        } else if (key == "max_total_rotation_deg") {
          o.max_total_rotation_deg = kv.second.as<double>();
        } else {
          throw ConfigError(path + ": server.planning." + key +
                            ": unknown key; expected max_targets, max_total_rotation_deg");
        }
      }
    }
    if (const YAML::Node sec = s["security"]) {
      for (const auto& kv : sec) {
        const std::string key = kv.first.Scalar();
        if (key == "identity") {
          const auto folder = kv.second.as<std::string>();
          o.security.identity = folder.empty() ? "" : resolve(base, folder);
        } else if (key == "plugins") {
          o.security.plugins = kv.second.as<std::string>();
        } else {
          throw ConfigError(path + ": server.security." + key +
                            ": unknown key; expected identity, plugins");
        }
      }
    }
    if (const YAML::Node g = s["openigtlink"]) {
      auto& go = o.openigtlink;
      for (const auto& kv : g) {
        const std::string key = kv.first.Scalar();
        if (key == "enabled") {
          go.enabled = kv.second.as<bool>();
        } else if (key == "address") {
          go.address = kv.second.as<std::string>();
        } else if (key == "port") {
          go.port = kv.second.as<int>();
        } else if (key == "timeout_s") {
          go.timeout_s = kv.second.as<double>();
        } else if (key == "allow_motion_approval") {
          go.allow_motion_approval = kv.second.as<bool>();
        } else {
          throw ConfigError(path + ": server.openigtlink." + key +
                            ": unknown key; expected enabled, address, port, timeout_s, "
                            "allow_motion_approval");
        }
      }
    }
    if (const YAML::Node a = s["approval"]) {
      for (const auto& kv : a) {
        const std::string key = kv.first.Scalar();
        if (key == "approvers") {
          o.approvers = kv.second.as<std::vector<std::string>>();
        } else if (key == "expiry_s") {
          o.approval_expiry_s = kv.second.as<double>();
        } else {
          throw ConfigError(path + ": server.approval." + key +
                            ": unknown key; expected approvers, expiry_s");
        }
      }
    }
  } catch (const YAML::Exception& e) {
    throw ConfigError(path + ": server: " + e.what());
  }
  if (auto bad = checkControllerOptions(o)) throw ConfigError(path + ": server." + *bad);
  return o;
}

int runServer(const ServerOptions& given, const std::atomic<bool>& stop) {
  ServerOptions options = given;
  // A site that lets OpenIGTLink release motion makes the bridge an approver (by its reserved id).
  if (options.openigtlink.enabled && options.openigtlink.allow_motion_approval) {
    options.approvers.push_back(igtl::kBridgeClientId);
  }
  auto robot = config::loadRobot(options.robot_config);
  if (!robot) {
    spdlog::error("{}", robot.error().message);
    return 2;
  }
  if (!options.tissue_name.empty()) {
    auto profiles = config::loadTissueProfiles(options.tissue_profiles);
    auto profile = profiles ? config::tissueProfile(*profiles, options.tissue_name)
                            : Expected<config::TissueProfile>(profiles.error());
    if (!profile) {
      spdlog::error("{}", profile.error().message);
      return 2;
    }
    options.tissue = std::move(profile).value();
  }
  if (!options.replay_session.empty()) {
    // Read only: a torn last record is left out, not cut off the file.
    const fs::path dir(options.replay_session);
    const std::string journal_path = (dir / "journal.jsonl").string();
    if (!fs::exists(journal_path)) {
      spdlog::error("{}: no journal in this folder", journal_path);
      return 2;
    }
    auto contents = journal::readJournal(journal_path);
    if (!contents) {
      spdlog::error("{}", contents.error().message);
      return 2;
    }
    if (contents->torn_tail)
      spdlog::warn("{}: the last record was cut short; left out", journal_path);
    try {
      Server server(options, std::make_shared<const config::Robot>(std::move(robot).value()), dir,
                    std::nullopt);
      return server.replay(stop, contents->lines);
    } catch (const DdsError& e) {
      spdlog::error("DDS: {}", e.what());
      return 1;
    }
  }
  fs::path dir = options.session_dir.empty()
                     ? fs::path(options.session_root.empty() ? "sessions" : options.session_root) /
                           sessionName()
                     : fs::path(options.session_dir);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    spdlog::error("{}: cannot create the session folder: {}", dir.string(), ec.message());
    return 2;
  }
  // An existing session is recovered from its journal; a write torn by a crash is cut off.
  const std::string journal_path = (dir / "journal.jsonl").string();
  auto contents = journal::readJournal(journal_path);
  if (!contents) {
    spdlog::error("{}", contents.error().message);
    return 2;
  }
  if (contents->torn_tail) {
    spdlog::warn("{}: the last record was cut short (a crash while writing); dropped",
                 journal_path);
    fs::resize_file(journal_path, contents->valid_bytes, ec);
    if (ec) {
      spdlog::error("{}: cannot drop the torn record: {}", journal_path, ec.message());
      return 2;
    }
  }
  auto journal = journal::Journal::open(journal_path);
  if (!journal) {
    spdlog::error("{}", journal.error().message);
    return 2;
  }
  try {
    Server server(options, std::make_shared<const config::Robot>(std::move(robot).value()), dir,
                  std::move(journal).value());
    return server.run(stop, contents->lines);
  } catch (const DdsError& e) {
    spdlog::error("DDS: {}", e.what());
    return 1;
  }
}

}  // namespace ignav::server
