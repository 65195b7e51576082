// The motor controller boundary. Drivers implement MotorController and know nothing of DDS or
// the workflow (ros2_control's rule); the server decides when a move may be sent.
//
// SimulatedController is a deterministic model of three stepper axes: trapezoidal profiles,
// step counting, limit switches and injectable faults. Time is an input (advanceTo), never read
// from a clock, so tests and replay see exactly the same motion.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "ignav/actuation/transmission.hpp"
#include "ignav/core/expected.hpp"

namespace ignav::actuation {

enum class ControllerState { kDisconnected, kIdle, kMoving, kFault };
const char* toString(ControllerState state);

struct ControllerStatus {
  ControllerState state = ControllerState::kDisconnected;
  Steps position;  // what the controller reports (TP)
  std::array<bool, 3> moving{false, false, false};
  std::string fault;  // why, when state is kFault
};

class MotorController {
 public:
  virtual ~MotorController() = default;
  virtual Status connect() = 0;
  // Defines the present position as zero on every axis (after a homing routine or a check).
  virtual Status home() = 0;
  // Starts a relative move of every axis at once; refused while moving or in a fault.
  virtual Status move(const Steps& increments) = 0;
  virtual Status stop() = 0;   // decelerate to rest
  virtual Status abort() = 0;  // halt at once
  virtual Expected<ControllerStatus> poll() = 0;
  virtual Status clearFault() = 0;
  // True when stop() and abort() may be called from another thread while any other call is in
  // progress (they then never wait behind it). Otherwise the caller serialises every call.
  virtual bool concurrentHalts() const { return false; }
};

// Rest-to-rest time of a trapezoidal move over `distance_steps` (sign ignored) at this speed and
// acceleration: what the simulated axes take, and the estimate approval requests show.
double trapezoidDuration_s(double distance_steps, double speed_steps_s,
                           double acceleration_steps_s2);

struct SimulatedAxis {
  double speed_steps_s = 2000.0;
  double acceleration_steps_s2 = 8000.0;
  std::int64_t min_steps = -1'000'000;  // limit switches
  std::int64_t max_steps = 1'000'000;
};

enum class InjectedFault {
  kNone,
  kStall,             // an axis stops halfway through the next move
  kLostConnection,    // every call fails until reconnected
  kPositionMismatch,  // the reported position drifts by 7 steps on the next move
};

class SimulatedController final : public MotorController {
 public:
  explicit SimulatedController(std::array<SimulatedAxis, 3> axes = {});

  Status connect() override;
  Status home() override;
  Status move(const Steps& increments) override;
  Status stop() override;
  Status abort() override;
  Expected<ControllerStatus> poll() override;
  Status clearFault() override;

  // Changes an axis' profile (SP/AC on a real controller); refused while it moves.
  Status setProfile(int axis, double speed_steps_s, double acceleration_steps_s2);
  // Where the motors stand at power-on (a real controller keeps counting across a restart of
  // its client; the simulation is told). Refused while moving.
  Status placeAt(const Steps& position);
  // Advances simulated time (seconds, monotone).
  void advanceTo(double time_s);
  double time_s() const { return now_s_; }
  void inject(InjectedFault fault, int axis = 0);
  // How many move() calls reached the motors: the boundary safety tests count.
  std::size_t movesStarted() const { return moves_started_; }

 private:
  struct Motion {
    double start_s = 0.0;
    double from = 0.0;
    double distance = 0.0;  // signed steps
    double stop_at = -1.0;  // decelerating from a stop() issued at this time (< 0: none)
    bool active = false;
  };
  double positionAt(int axis, double t) const;
  Status usable() const;

  std::array<SimulatedAxis, 3> axes_;
  std::array<Motion, 3> motion_{};
  std::array<double, 3> rest_{0.0, 0.0, 0.0};
  double now_s_ = 0.0;
  bool connected_ = false;
  std::string fault_;
  InjectedFault injected_ = InjectedFault::kNone;
  int injected_axis_ = 0;
  std::int64_t reported_offset_ = 0;
  std::size_t moves_started_ = 0;
};

}  // namespace ignav::actuation
