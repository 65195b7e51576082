// The Server's side of the controller component (controller_component.hpp): starting it with the
// driver the options name, handing it the reducer's commands, and turning what it reports
// (readings, failed commands) into MotionState and reducer inputs. The event loop never calls a
// driver.
#include <spdlog/spdlog.h>

#include <array>
#include <thread>
#include <tuple>
#include <utility>

#include "ignav/actuation/galil.hpp"
#include "server_core.hpp"

namespace ignav::server {
namespace {

using workflow::Input;
using workflow::InputKind;

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

}  // namespace

// Started (and its first connection tried) before the first input. Inputs that need a reading
// wait for that first attempt, within a bound.
void Server::startController(bool home, const std::optional<actuation::Steps>& place_at) {
  ControllerComponentOptions co;
  co.name = controller_name_;
  co.active_period = std::chrono::milliseconds(options_.controller.control_period_ms);
  co.home_on_first_connect = home;
  component_ = std::make_unique<ControllerComponent>(makeDriver(options_.controller, place_at), co,
                                                     [this] { waitset_.trigger(); });
  component_->start();
  // Connect, set up (4 replies), home, read (3): each within the driver's timeout.
  const auto bound = std::chrono::milliseconds(10 * options_.controller.timeout_ms + 1000);
  if (!component_->waitForFirstReading(bound)) {
    spdlog::error("controller {}: no answer within {} ms; going on without it", controller_name_,
                  bound.count());
  }
  (void)component_->take();  // the first reading is the latest: nothing to judge yet
  last_reading_ = latestReading().status;
  lifecycle_ = latestReading().lifecycle;
  if (last_reading_.state == actuation::ControllerState::kDisconnected) {
    spdlog::error("controller {}: {}", controller_name_, last_reading_.fault);
  }
}

ControllerReading Server::latestReading() const {
  if (component_) return component_->latest();
  ControllerReading r;
  r.status.fault = "no controller";
  return r;
}

// A controller command from the reducer, to the component's mailbox. Its failure comes back as
// an event (takeControllerEvents). The one place a workflow command becomes a motor command: a
// move goes out only if it is exactly one move of an intact approval
// (ControllerCommand::releasable); anything else halts the robot and becomes a fault.
void Server::runController(const workflow::ControllerCommand& c) {
  if (!component_) return;
  const auto released = MotorCommand::release(c);
  if (!released) {
    refused_move_ = "refused to send a move that is not exactly what was approved";
    spdlog::critical("{}", refused_move_);
    last_submitted_ =
        component_->submit(*MotorCommand::release(workflow::ControllerCommand::abort()));
    return;
  }
  const std::uint64_t seq = component_->submit(*released);
  last_submitted_ = seq;
  if (c.action() == workflow::ControllerAction::kMove) move_seq_ = seq;
}

// What the controller component reported since last time: readings are published (and shown to
// Slicer), a finished move or a fault becomes the reducer's input.
void Server::takeControllerEvents() {
  if (!component_) return;
  if (!refused_move_.empty()) {
    Input fault;
    fault.kind = InputKind::kControllerFault;
    fault.controller = component_->latest().status;
    fault.controller->state = actuation::ControllerState::kFault;
    fault.controller->fault = std::exchange(refused_move_, std::string());
    step(fault);
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
      step(std::move(fault));
      continue;
    }
    onReading(ev.reading);
  }
}

void Server::onReading(const ControllerReading& reading) {
  const auto before = last_reading_;
  const auto& r = reading.status;
  last_reading_ = r;
  const bool changed = r.state != before.state || r.position != before.position ||
                       r.fault != before.fault || reading.lifecycle != lifecycle_;
  lifecycle_ = reading.lifecycle;
  if (changed) publishMotion();
  if (igtl_) {
    // When the reading was taken, on the server's wall clock (what OpenIGTLink stamps).
    const double age_s =
        reading.taken == std::chrono::steady_clock::time_point{}
            ? 0.0
            : std::chrono::duration<double>(std::chrono::steady_clock::now() - reading.taken)
                  .count();
    igtl_->onReading(session_, r, before, wallS() - age_s);
  }
  const bool moving = r.state == actuation::ControllerState::kMoving;
  const bool bad = r.state == actuation::ControllerState::kDisconnected ||
                   r.state == actuation::ControllerState::kFault;
  // A segment is done on a reading taken after its move was sent, at rest (or on a fault).
  if (session_.phase == workflow::Phase::kMoving && session_.motion && !moving &&
      (bad || reading.after_command >= move_seq_)) {
    if (bad) last_fault_reported_ = r.fault;
    Input done;
    done.kind = InputKind::kSegmentDone;
    done.controller = r;
    step(std::move(done));
    return;
  }
  if (!bad) {
    last_fault_reported_.clear();
    return;
  }
  if (r.fault == last_fault_reported_) return;
  last_fault_reported_ = r.fault;
  Input fault;
  fault.kind = InputKind::kControllerFault;
  fault.controller = r;
  step(std::move(fault));
}

// ---- one robot, one server: the robot-id check that gates the controller's start ----

// Another server's Health in this robot's partition: the later one to start gives way (ties by
// session id, host and folder, so exactly one of two gives way). A later one is said once; it will
// stop. This server's own Health is the one with its start, session, host and folder: the session
// id alone (the folder's name) is not, since two servers may be given folders of one name.
std::optional<std::string> Server::robotIdConflict() {
  std::optional<std::string> conflict;
  const std::string folder = session_dir_.string();
  const auto mine = std::tie(started_unix_s_, session_.session_id, host_, folder);
  robot_peers_.take([&](const protocol::Health& h) {
    if (h.robot_id != options_.robot_id) return;
    const auto theirs = std::tie(h.started_unix_s, h.session_id, h.host, h.session_dir);
    if (theirs == mine) return;
    const bool it_is_older = theirs < mine;
    const std::string who = fmt::format("session {} on host {}, serving since {:.0f}", h.session_id,
                                        h.host, h.started_unix_s);
    if (it_is_older) {
      conflict = fmt::format(
          "robot_id '{}': another ignav-server already serves this robot on DDS domain {} ({}); "
          "two servers must never act on one robot's commands: give each robot its own "
          "server.robot_id",
          options_.robot_id, options_.domain_id, who);
    } else if (peers_warned_.insert(h.session_dir + "@" + h.host).second) {
      spdlog::warn(
          "robot_id '{}': a later ignav-server with this robot id appeared ({}); it "
          "gives way to this one",
          options_.robot_id, who);
    }
  });
  return conflict;
}

// No other server with this robot id was heard for robot_id_check_ms: the controller starts
// (a new session's robot is at its home, where its position is zero; a recovered one's
// simulation is placed where the journal last verified the motors, a real controller kept
// counting), a recovered session is judged on its first reading, and what waited is released.
void Server::startControllerWhenClear() {
  startController(!recovering_,
                  recovering_ ? std::optional<actuation::Steps>(session_.position) : std::nullopt);
  if (recovering_) {
    // Approvals die here, and the position is checked against the controller's.
    Input restarted;
    restarted.kind = InputKind::kServerRestarted;
    stepNow(std::move(restarted));
  }
  publishMotion();
  waitset_.trigger();  // what finished meanwhile (a load, a detection) is taken at once
}

// Announces this server, then listens for robot_id_check_ms (from the start of the process's
// participant) for another with its robot id; commands wait in DDS meanwhile. 0: not at start,
// only once serving (robotIdConflict in the loop).
std::optional<std::string> Server::checkRobotIdAtStart() {
  publishHealth();
  if (options_.robot_id_check_ms == 0) return std::nullopt;
  const auto end = participant_started_ + std::chrono::milliseconds(options_.robot_id_check_ms);
  for (;;) {
    if (auto conflict = robotIdConflict()) return conflict;
    if (Clock::now() >= end) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

}  // namespace ignav::server
