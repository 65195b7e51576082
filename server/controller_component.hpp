// The motor controller as a hardware component with a lifecycle, on threads of its own (the
// ros2_control lesson): the server never calls a driver. It submits commands and takes readings
// and events through this mailbox; the component connects, executes, reads the controller every
// cycle, reconnects with backoff, and wakes the server (its DDS waitset's guard) when something
// changed. docs/ARCHITECTURE.md draws it.
//
// Two threads:
// - the cycle thread: connect, then each cycle execute the queued commands (moves, home, clear
//   fault) and read() the controller: every control period while the robot moves, every rest
//   period otherwise.
// - the halt thread: stop and abort only. A halt drops every move queued behind it and goes to
//   the driver at once; a driver with concurrentHalts() (Galil: a TCP handle of its own) is not
//   waited for even while a poll waits for its reply, the others (the simulation, which never
//   blocks) take the driver lock. A move being sent while a halt came is halted again after it.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "ignav/actuation/controller.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::server {

// unconfigured -> connecting -> active <-> lost (reconnecting with backoff) -> shut down
enum class Lifecycle { kUnconfigured, kConnecting, kActive, kLost, kShutDown };
const char* toString(Lifecycle lifecycle);

struct ControllerReading {
  actuation::ControllerStatus status;  // kDisconnected (with why, in fault) while not connected
  // Every command submitted with this sequence number or a lower one (halts too) had been
  // executed (or had failed, or was dropped by a halt) before this reading was taken: a move's
  // arrival, and a position check, are judged only on a reading taken after the commands before.
  std::uint64_t after_command = 0;
  // When the read began: the reading shows the controller as it was at this moment or later (an
  // approval is judged only on a reading begun after it arrived: a hand jog just before it).
  std::chrono::steady_clock::time_point taken{};
  // The component's lifecycle as this reading left it: a change of lifecycle alone is an event
  // too, so that MotionState.lifecycle follows reconnection (issue 22).
  Lifecycle lifecycle = Lifecycle::kUnconfigured;
};

struct ControllerEvent {
  enum class Kind { kReading, kCommandFailed };
  Kind kind = Kind::kReading;
  ControllerReading reading;  // kReading: the new reading; kCommandFailed: the latest one
  std::uint64_t command = 0;  // kCommandFailed: its sequence number, action and why
  workflow::ControllerAction action = workflow::ControllerAction::kStop;
  std::string why;
};

struct ControllerComponentOptions {
  std::string name;                                // for the log ("galil 127.0.0.1:23")
  std::chrono::milliseconds active_period{10};     // read() period while moving
  std::chrono::milliseconds rest_period{200};      // ... at rest
  std::chrono::milliseconds reconnect_first{250};  // backoff after a lost connection,
  std::chrono::milliseconds reconnect_max{4000};   // doubling up to this
  bool home_on_first_connect = false;              // a new session: the robot is at home
};

// What the component sends to the driver, made only by release(): a move exists only as released
// from a workflow::ControllerCommand that is releasable (its approval intact, the increments
// exactly its segment's), and carries that approval's digest and the position its segment starts
// from, so nothing but an approved move can reach the motors and none goes unless the robot rests
// where its approval said. The component and the drivers know nothing else of approvals, as a
// ros2_control hardware interface knows nothing of topics.
class MotorCommand {
 public:
  // Nothing for a move that is not exactly as approved; every other action is released as it is.
  static std::optional<MotorCommand> release(const workflow::ControllerCommand& command);

  workflow::ControllerAction action() const { return action_; }
  const actuation::Steps& increments() const { return increments_; }  // a move's; else zero
  const actuation::Steps& startsAt() const { return starts_at_; }     // a move's
  const std::string& digest() const { return digest_; }               // a move's approval's
  bool isHalt() const {
    return action_ == workflow::ControllerAction::kStop ||
           action_ == workflow::ControllerAction::kAbort;
  }

 private:
  explicit MotorCommand(workflow::ControllerAction action) : action_(action) {}
  workflow::ControllerAction action_;
  actuation::Steps increments_;
  actuation::Steps starts_at_;
  std::string digest_;
};

class ControllerComponent {
 public:
  // `wake` is called (from the component's threads) whenever events are waiting.
  ControllerComponent(std::unique_ptr<actuation::MotorController> driver,
                      ControllerComponentOptions options, std::function<void()> wake);
  ~ControllerComponent();  // shutdown()
  ControllerComponent(const ControllerComponent&) = delete;
  ControllerComponent& operator=(const ControllerComponent&) = delete;

  void start();     // configure: the threads start and the first connection is attempted
  void shutdown();  // the threads end (a call in flight finishes, within the driver's timeout)

  // Queues a command; returns its sequence number. A halt (stop, abort) pre-empts: queued moves
  // are dropped and it goes to the controller at once. A move is sent only if a reading taken
  // just before shows the robot at rest where it starts (else it fails, with why).
  std::uint64_t submit(const MotorCommand& command);

  ControllerReading latest() const;                             // the last reading (any thread)
  std::vector<ControllerEvent> take();                          // the events since the last take
  bool waitForFirstReading(std::chrono::milliseconds timeout);  // the first connection tried
  void reconnectNow();  // an operator's reset: do not wait for the backoff
  void pollNow();       // a reading is wanted: take the next one at once
  Lifecycle lifecycle() const;

 private:
  using Clock = std::chrono::steady_clock;
  struct Queued {
    std::uint64_t seq = 0;
    MotorCommand command;
  };
  void cycleLoop();
  void haltLoop();
  void connectOnce();
  void pollOnce(bool force_event);
  void execute(const Queued& q);
  Status halt(workflow::ControllerAction action);
  // Runs a driver call on the cycle thread (the simulation's clock advanced first).
  template <typename F>
  auto call(F&& f) -> decltype(f());
  void lost(const std::string& why);
  void publish(ControllerReading reading, bool force_event);
  void failed(std::uint64_t seq, workflow::ControllerAction action, const std::string& why);
  void setLifecycle(Lifecycle l);
  std::uint64_t completed() const;   // the reading's after_command, now
  void finished(std::uint64_t seq);  // executed, failed or dropped
  double clock_s() const;

  std::unique_ptr<actuation::MotorController> driver_;
  actuation::SimulatedController* sim_ = nullptr;  // time-driven: advanced before every call
  ControllerComponentOptions options_;
  std::function<void()> wake_;
  const Clock::time_point epoch_ = Clock::now();

  std::mutex driver_mutex_;   // every driver call but concurrent halts
  mutable std::mutex mutex_;  // all below
  std::condition_variable cycle_cv_, halt_cv_, first_cv_;
  std::deque<Queued> queue_;
  std::deque<std::pair<std::uint64_t, workflow::ControllerAction>> halts_;
  std::set<std::uint64_t> pending_;  // submitted, not yet executed, failed or dropped
  std::vector<ControllerEvent> events_;
  ControllerReading latest_;
  Lifecycle lifecycle_ = Lifecycle::kUnconfigured;
  std::uint64_t next_seq_ = 0;
  std::atomic<std::uint64_t> halt_epoch_{0};
  workflow::ControllerAction last_halt_ = workflow::ControllerAction::kAbort;
  bool stopping_ = false;
  bool first_done_ = false;
  bool reconnect_now_ = false;
  Clock::time_point next_poll_{}, next_attempt_{};

  // The cycle thread's own.
  bool connected_ = false;
  bool attempted_ = false;
  bool moving_ = false;
  std::chrono::milliseconds backoff_{0};

  std::thread cycle_, halter_;
};

}  // namespace ignav::server
