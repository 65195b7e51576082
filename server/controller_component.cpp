#include "controller_component.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace ignav::server {
namespace {

using workflow::ControllerAction;

// Errors that mean the connection is gone (or out of step): reconnect.
bool connectionError(const Error& e) {
  return e.reason == "timeout" || e.reason == "connection_lost" || e.reason == "disconnected";
}

bool sameStatus(const actuation::ControllerStatus& a, const actuation::ControllerStatus& b) {
  return a.state == b.state && a.position == b.position && a.moving == b.moving &&
         a.fault == b.fault;
}

}  // namespace

const char* toString(Lifecycle lifecycle) {
  switch (lifecycle) {
    case Lifecycle::kUnconfigured:
      return "unconfigured";
    case Lifecycle::kConnecting:
      return "connecting";
    case Lifecycle::kActive:
      return "active";
    case Lifecycle::kLost:
      return "lost";
    case Lifecycle::kShutDown:
      return "shut_down";
  }
  return "?";
}

ControllerComponent::ControllerComponent(std::unique_ptr<actuation::MotorController> driver,
                                         ControllerComponentOptions options,
                                         std::function<void()> wake)
    : driver_(std::move(driver)),
      sim_(dynamic_cast<actuation::SimulatedController*>(driver_.get())),
      options_(std::move(options)),
      wake_(std::move(wake)) {
  latest_.status.fault = "not connected yet";
}

ControllerComponent::~ControllerComponent() {
  shutdown();
}

void ControllerComponent::start() {
  setLifecycle(Lifecycle::kConnecting);
  cycle_ = std::thread([this] { cycleLoop(); });
  halter_ = std::thread([this] { haltLoop(); });
}

void ControllerComponent::shutdown() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  cycle_cv_.notify_all();
  halt_cv_.notify_all();
  first_cv_.notify_all();
  if (cycle_.joinable()) cycle_.join();
  if (halter_.joinable()) halter_.join();
  std::lock_guard<std::mutex> lock(mutex_);
  lifecycle_ = Lifecycle::kShutDown;
}

double ControllerComponent::clock_s() const {
  return std::chrono::duration<double>(Clock::now() - epoch_).count();
}

std::optional<MotorCommand> MotorCommand::release(const workflow::ControllerCommand& command) {
  if (!command.releasable()) return std::nullopt;
  MotorCommand released(command.action());
  if (command.action() == workflow::ControllerAction::kMove) {
    released.increments_ = command.increments();
    released.starts_at_ = command.segmentStart();
    released.digest_ = command.approval()->request().digest;
  }
  return released;
}

std::uint64_t ControllerComponent::submit(const MotorCommand& command) {
  std::uint64_t seq = 0;
  if (command.isHalt()) {
    std::size_t dropped = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      seq = ++next_seq_;
      const auto before = queue_.size();
      queue_.erase(std::remove_if(queue_.begin(), queue_.end(),
                                  [this](const Queued& q) {
                                    if (q.command.action() != ControllerAction::kMove) {
                                      return false;
                                    }
                                    pending_.erase(q.seq);
                                    return true;
                                  }),
                   queue_.end());
      dropped = before - queue_.size();
      pending_.insert(seq);
      last_halt_ = command.action();
      ++halt_epoch_;
      halts_.emplace_back(seq, command.action());
      next_poll_ = Clock::now();  // show the robot at rest as soon as it is
    }
    halt_cv_.notify_one();
    if (dropped > 0) spdlog::warn("controller: {} queued move(s) dropped by a halt", dropped);
    return seq;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    seq = ++next_seq_;
    pending_.insert(seq);
    queue_.push_back({seq, command});
  }
  cycle_cv_.notify_one();
  return seq;
}

ControllerReading ControllerComponent::latest() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return latest_;
}

std::vector<ControllerEvent> ControllerComponent::take() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<ControllerEvent> out;
  out.swap(events_);
  return out;
}

bool ControllerComponent::waitForFirstReading(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  return first_cv_.wait_for(lock, timeout, [this] { return first_done_ || stopping_; });
}

void ControllerComponent::pollNow() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    next_poll_ = Clock::now();
  }
  cycle_cv_.notify_one();
}

std::uint64_t ControllerComponent::completed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pending_.empty() ? next_seq_ : *pending_.begin() - 1;
}

void ControllerComponent::finished(std::uint64_t seq) {
  std::lock_guard<std::mutex> lock(mutex_);
  pending_.erase(seq);
}

void ControllerComponent::reconnectNow() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    reconnect_now_ = true;
  }
  cycle_cv_.notify_one();
}

Lifecycle ControllerComponent::lifecycle() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return lifecycle_;
}

void ControllerComponent::setLifecycle(Lifecycle l) {
  Lifecycle before;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    before = lifecycle_;
    lifecycle_ = l;
  }
  if (before != l) spdlog::info("controller {}: {}", options_.name, toString(l));
}

template <typename F>
auto ControllerComponent::call(F&& f) -> decltype(f()) {
  std::lock_guard<std::mutex> lock(driver_mutex_);
  if (sim_) sim_->advanceTo(clock_s());
  return f();
}

void ControllerComponent::cycleLoop() {
  for (;;) {
    std::optional<Queued> next;
    bool connect = false;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      for (;;) {
        if (stopping_) return;
        if (!queue_.empty()) {
          next = std::move(queue_.front());
          queue_.pop_front();
          break;
        }
        if (!connected_) {
          if (reconnect_now_ || !attempted_ || Clock::now() >= next_attempt_) {
            reconnect_now_ = false;
            connect = true;
            break;
          }
          cycle_cv_.wait_until(lock, next_attempt_);
          continue;
        }
        if (Clock::now() >= next_poll_) break;
        cycle_cv_.wait_until(lock, next_poll_);
      }
    }
    if (connect) {
      connectOnce();
      continue;
    }
    if (next) execute(*next);
    if (connected_) pollOnce(next.has_value());
    std::lock_guard<std::mutex> lock(mutex_);
    // While the queue holds more, they run at once (the poll between them shows their effect).
    next_poll_ = std::max(next_poll_,
                          Clock::now() + (moving_ ? options_.active_period : options_.rest_period));
  }
}

void ControllerComponent::connectOnce() {
  const bool first = !attempted_;
  attempted_ = true;
  auto ok = call([&] { return driver_->connect(); });
  if (ok && first && options_.home_on_first_connect) {
    // A new session starts with the robot at its home: that position is zero.
    if (auto homed = call([&] { return driver_->home(); }); !homed) {
      spdlog::error("controller {}: home: {}", options_.name, homed.error().message);
    }
  }
  if (ok) {
    connected_ = true;
    backoff_ = options_.reconnect_first;
    setLifecycle(Lifecycle::kActive);
    pollOnce(true);
  } else {
    // The reading keeps the reason the connection was lost; each failed attempt is logged only
    // (a fault reported again and again would fill the journal: docs/RELIABILITY.md R1).
    spdlog::log(
        first || backoff_ >= options_.reconnect_max ? spdlog::level::warn : spdlog::level::info,
        "controller {}: {}; next attempt in {} ms", options_.name, ok.error().message,
        std::max(backoff_, options_.reconnect_first).count());
    setLifecycle(first ? Lifecycle::kConnecting : Lifecycle::kLost);
    ControllerReading r = latest();  // the same reading, in its new lifecycle
    if (first) {
      r.status.state = actuation::ControllerState::kDisconnected;
      r.status.fault = ok.error().message;
      r.after_command = completed();
      r.taken = Clock::now();
    }
    publish(std::move(r), first);
    backoff_ = std::clamp(backoff_ * 2, options_.reconnect_first, options_.reconnect_max);
    std::lock_guard<std::mutex> lock(mutex_);
    next_attempt_ = Clock::now() + backoff_;
  }
  if (first) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      first_done_ = true;
    }
    first_cv_.notify_all();
  }
}

// The connection is gone: say so once (with why), then reconnect with backoff.
void ControllerComponent::lost(const std::string& why) {
  connected_ = false;
  moving_ = false;
  ControllerReading r;
  r.status.state = actuation::ControllerState::kDisconnected;
  r.status.fault = why;
  r.after_command = completed();
  r.taken = Clock::now();
  setLifecycle(Lifecycle::kLost);
  publish(std::move(r), false);
  backoff_ = options_.reconnect_first;
  std::lock_guard<std::mutex> lock(mutex_);
  next_attempt_ = Clock::now() + backoff_;
}

void ControllerComponent::pollOnce(bool force_event) {
  const std::uint64_t after = completed();
  const auto began = Clock::now();  // what the reading shows was true at or after this
  auto polled = call([&] { return driver_->poll(); });
  if (!polled) {
    if (connectionError(polled.error())) return lost(polled.error().message);
    ControllerReading r;  // an answer we cannot read: not a reading of the robot
    r.status.state = actuation::ControllerState::kDisconnected;
    r.status.fault = polled.error().message;
    r.after_command = after;
    r.taken = began;
    return publish(std::move(r), force_event);
  }
  moving_ = polled->state == actuation::ControllerState::kMoving;
  ControllerReading r;
  r.status = std::move(polled).value();
  r.after_command = after;
  r.taken = began;
  publish(std::move(r), force_event);
}

void ControllerComponent::publish(ControllerReading reading, bool force_event) {
  bool event = force_event;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    reading.lifecycle = lifecycle_;
    event = event || !sameStatus(reading.status, latest_.status) ||
            reading.after_command != latest_.after_command ||
            reading.lifecycle != latest_.lifecycle;
    latest_ = reading;
    if (event) {
      ControllerEvent e;
      e.kind = ControllerEvent::Kind::kReading;
      e.reading = std::move(reading);
      events_.push_back(std::move(e));
    }
  }
  if (event && wake_) wake_();
}

void ControllerComponent::failed(std::uint64_t seq, ControllerAction action,
                                 const std::string& why) {
  spdlog::error("controller {}: {} (command {}): {}", options_.name, workflow::toString(action),
                seq, why);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ControllerEvent e;
    e.kind = ControllerEvent::Kind::kCommandFailed;
    e.reading = latest_;
    e.command = seq;
    e.action = action;
    e.why = why;
    events_.push_back(std::move(e));
  }
  if (wake_) wake_();
}

void ControllerComponent::execute(const Queued& q) {
  if (!connected_) {
    // Not sent: the reading already says why the controller is away (reconnection is ours).
    failed(q.seq, q.command.action(), "the controller is not connected: " + latest().status.fault);
    finished(q.seq);
    return;
  }
  const std::uint64_t epoch = halt_epoch_.load();
  Status done = Ok{};
  switch (q.command.action()) {
    case ControllerAction::kMove: {
      // The approval was judged on the last reading; the move goes only if the robot is still at
      // rest where that approval says its segment starts, read just now.
      {
        auto now = call([&] { return driver_->poll(); });
        if (!now) {
          done = now.error();
        } else if (now->state != actuation::ControllerState::kIdle) {
          done = makeError(ErrorCode::kInvalidArgument,
                           std::string("move not sent: the controller is ") +
                               actuation::toString(now->state) +
                               (now->fault.empty() ? "" : " (" + now->fault + ")"),
                           "not_at_rest");
        } else if (now->position != q.command.startsAt()) {
          const auto& p = now->position.motor;
          const auto& e = q.command.startsAt().motor;
          done = makeError(ErrorCode::kInvalidArgument,
                           fmt::format("move not sent: the motors are at {} / {} / {} steps, "
                                       "not at {} / {} / {} where the approved move starts",
                                       p[0], p[1], p[2], e[0], e[1], e[2]),
                           "position_changed");
        }
      }
      if (done && halt_epoch_.load() == epoch) {
        spdlog::info("controller {}: move {} of approval {} sent", options_.name, q.seq,
                     q.command.digest().substr(0, 12));
        done = call([&] { return driver_->move(q.command.increments()); });
        if (done) moving_ = true;
      } else if (done) {
        spdlog::warn("controller {}: move {} not sent: a halt came first", options_.name, q.seq);
      }
      break;
    }
    case ControllerAction::kHome:
      done = call([&] { return driver_->home(); });
      break;
    case ControllerAction::kClearFault:
      done = call([&] { return driver_->clearFault(); });
      break;
    case ControllerAction::kStop:
    case ControllerAction::kAbort:
      break;  // never queued here (the halt thread's)
  }
  finished(q.seq);
  // A halt that came while the move was on its way may have reached the controller before it:
  // halt again, after it.
  if (q.command.action() == ControllerAction::kMove && halt_epoch_.load() != epoch) {
    workflow::ControllerAction again;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      again = last_halt_;
    }
    spdlog::warn("controller {}: a halt came while move {} was being sent: halting again",
                 options_.name, q.seq);
    (void)halt(again);
  }
  if (!done) {
    // A move that a halt kept from beginning is not a fault: the halt took the motion away.
    if (q.command.action() != ControllerAction::kMove || halt_epoch_.load() == epoch ||
        done.error().reason != "halted") {
      failed(q.seq, q.command.action(), done.error().message);
    }
    if (connectionError(done.error())) lost(done.error().message);
  }
}

Status ControllerComponent::halt(ControllerAction action) {
  auto run = [&] {
    return action == ControllerAction::kAbort ? driver_->abort() : driver_->stop();
  };
  if (driver_->concurrentHalts()) return run();
  return call(run);
}

void ControllerComponent::haltLoop() {
  for (;;) {
    std::uint64_t seq = 0;
    std::vector<std::uint64_t> seqs;
    ControllerAction action = ControllerAction::kStop;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      halt_cv_.wait(lock, [this] { return stopping_ || !halts_.empty(); });
      if (stopping_) return;
      // Halts that piled up (a silent controller) go as one: the strongest of them.
      while (!halts_.empty()) {
        seq = halts_.front().first;
        seqs.push_back(seq);
        if (halts_.front().second == ControllerAction::kAbort) action = ControllerAction::kAbort;
        halts_.pop_front();
      }
    }
    const auto halted = halt(action);
    if (!halted) failed(seq, action, halted.error().message);
    for (const auto s : seqs)
      finished(s);
    cycle_cv_.notify_one();  // read the robot at rest soon
  }
}

}  // namespace ignav::server
