#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "ignav/actuation/controller.hpp"

namespace ignav::actuation {
namespace {

// Distance covered after tau seconds of a rest-to-rest trapezoid over `d` (>= 0) steps, and
// the trapezoid's duration.
struct Trapezoid {
  double d, v, a, t_ramp, t_total, peak;
  Trapezoid(double distance, double speed, double accel) : d(distance), v(speed), a(accel) {
    if (d >= v * v / a) {
      t_ramp = v / a;
      peak = v;
      t_total = 2 * t_ramp + (d - v * v / a) / v;
    } else {
      t_ramp = std::sqrt(d / a);
      peak = a * t_ramp;
      t_total = 2 * t_ramp;
    }
  }
  double at(double tau) const {
    if (tau <= 0) return 0.0;
    if (tau >= t_total) return d;
    if (tau < t_ramp) return 0.5 * a * tau * tau;
    const double ramp_d = 0.5 * a * t_ramp * t_ramp;
    if (tau <= t_total - t_ramp) return ramp_d + peak * (tau - t_ramp);
    const double left = t_total - tau;
    return d - 0.5 * a * left * left;
  }
  double speedAt(double tau) const {
    if (tau <= 0 || tau >= t_total) return 0.0;
    if (tau < t_ramp) return a * tau;
    if (tau <= t_total - t_ramp) return peak;
    return a * (t_total - tau);
  }
};

}  // namespace

double trapezoidDuration_s(double distance_steps, double speed_steps_s,
                           double acceleration_steps_s2) {
  if (distance_steps == 0.0) return 0.0;
  return Trapezoid(std::abs(distance_steps), speed_steps_s, acceleration_steps_s2).t_total;
}

const char* toString(ControllerState state) {
  switch (state) {
    case ControllerState::kDisconnected:
      return "disconnected";
    case ControllerState::kIdle:
      return "idle";
    case ControllerState::kMoving:
      return "moving";
    case ControllerState::kFault:
      return "fault";
  }
  return "unknown";
}

SimulatedController::SimulatedController(std::array<SimulatedAxis, 3> axes) : axes_(axes) {}

Status SimulatedController::usable() const {
  if (injected_ == InjectedFault::kLostConnection) {
    return makeError(ErrorCode::kIo, "controller connection lost", "connection_lost");
  }
  if (!connected_) return makeError(ErrorCode::kIo, "controller not connected", "disconnected");
  return Ok{};
}

Status SimulatedController::connect() {
  if (injected_ == InjectedFault::kLostConnection) injected_ = InjectedFault::kNone;
  connected_ = true;
  return Ok{};
}

double SimulatedController::positionAt(int axis, double t) const {
  const Motion& m = motion_[static_cast<std::size_t>(axis)];
  if (!m.active) return rest_[static_cast<std::size_t>(axis)];
  const auto& ax = axes_[static_cast<std::size_t>(axis)];
  const double sign = m.distance < 0 ? -1.0 : 1.0;
  return m.from + sign * Trapezoid(std::abs(m.distance), ax.speed_steps_s, ax.acceleration_steps_s2)
                             .at(t - m.start_s);
}

Status SimulatedController::home() {
  if (auto ok = usable(); !ok) return ok;
  if (std::any_of(motion_.begin(), motion_.end(), [](const Motion& m) { return m.active; })) {
    return makeError(ErrorCode::kInvalidArgument, "cannot home while moving", "moving");
  }
  rest_ = {0.0, 0.0, 0.0};
  reported_offset_ = 0;
  return Ok{};
}

Status SimulatedController::move(const Steps& increments) {
  if (auto ok = usable(); !ok) return ok;
  (void)poll();  // settle finished motions first
  if (!fault_.empty()) {
    return makeError(ErrorCode::kInvalidArgument, "controller in fault: " + fault_, "fault");
  }
  for (int a = 0; a < 3; ++a) {
    if (motion_[static_cast<std::size_t>(a)].active) {
      return makeError(ErrorCode::kInvalidArgument, fmt::format("motor {} is still moving", a + 1),
                       "moving");
    }
  }
  ++moves_started_;
  for (std::size_t a = 0; a < 3; ++a) {
    double distance = static_cast<double>(increments.motor[a]);
    const double target = rest_[a] + distance;
    // A limit switch stops the axis at the limit.
    const double clipped = std::clamp(target, static_cast<double>(axes_[a].min_steps),
                                      static_cast<double>(axes_[a].max_steps));
    distance = clipped - rest_[a];
    if (injected_ == InjectedFault::kStall && static_cast<int>(a) == injected_axis_) {
      distance = std::trunc(distance / 2);  // it will stop halfway
    }
    motion_[a] = {now_s_, rest_[a], distance, -1.0, distance != 0.0};
  }
  return Ok{};
}

Status SimulatedController::stop() {
  if (auto ok = usable(); !ok) return ok;
  for (std::size_t a = 0; a < 3; ++a) {
    Motion& m = motion_[a];
    if (!m.active) continue;
    const auto& ax = axes_[a];
    const Trapezoid tr(std::abs(m.distance), ax.speed_steps_s, ax.acceleration_steps_s2);
    const double tau = now_s_ - m.start_s;
    const double sign = m.distance < 0 ? -1.0 : 1.0;
    const double v0 = tr.speedAt(tau);
    // Decelerate from v0 at the axis' acceleration: v0² / 2a more steps, whole steps only.
    const double more = std::min(std::round(v0 * v0 / (2 * ax.acceleration_steps_s2)),
                                 std::abs(m.distance) - std::floor(tr.at(tau)));
    const double here = m.from + sign * std::floor(tr.at(tau));
    m = {now_s_, here, sign * more, -1.0, more > 0.0};
    if (!m.active) rest_[a] = here;
  }
  return Ok{};
}

Status SimulatedController::abort() {
  if (auto ok = usable(); !ok) return ok;
  for (std::size_t a = 0; a < 3; ++a) {
    if (!motion_[a].active) continue;
    rest_[a] = std::round(positionAt(static_cast<int>(a), now_s_));
    motion_[a].active = false;
  }
  return Ok{};
}

Expected<ControllerStatus> SimulatedController::poll() {
  if (auto ok = usable(); !ok) return ok.error();
  ControllerStatus s;
  for (std::size_t a = 0; a < 3; ++a) {
    Motion& m = motion_[a];
    if (m.active) {
      const auto& ax = axes_[a];
      const Trapezoid tr(std::abs(m.distance), ax.speed_steps_s, ax.acceleration_steps_s2);
      if (now_s_ - m.start_s >= tr.t_total) {  // arrived
        rest_[a] = m.from + m.distance;
        m.active = false;
        const auto at = static_cast<std::int64_t>(rest_[a]);
        if (injected_ == InjectedFault::kStall && static_cast<int>(a) == injected_axis_) {
          fault_ = fmt::format("motor {} stalled at {} steps", a + 1, at);
          injected_ = InjectedFault::kNone;
        } else if (at == ax.min_steps || at == ax.max_steps) {
          fault_ = fmt::format("motor {} hit its limit switch at {} steps", a + 1, at);
        }
        if (injected_ == InjectedFault::kPositionMismatch &&
            static_cast<int>(a) == injected_axis_) {
          reported_offset_ += 7;
          injected_ = InjectedFault::kNone;
        }
      }
    }
    s.moving[a] = m.active;
    double p = positionAt(static_cast<int>(a), now_s_);
    if (static_cast<int>(a) == injected_axis_) p += static_cast<double>(reported_offset_);
    s.position.motor[a] = static_cast<std::int64_t>(std::floor(p + 1e-9));
  }
  s.fault = fault_;
  s.state = !fault_.empty() ? ControllerState::kFault
            : std::any_of(s.moving.begin(), s.moving.end(), [](bool b) { return b; })
                ? ControllerState::kMoving
                : ControllerState::kIdle;
  return s;
}

Status SimulatedController::clearFault() {
  if (auto ok = usable(); !ok) return ok;
  fault_.clear();
  return Ok{};
}

Status SimulatedController::setProfile(int axis, double speed_steps_s,
                                       double acceleration_steps_s2) {
  if (axis < 0 || axis > 2 || !(speed_steps_s > 0) || !(acceleration_steps_s2 > 0) ||
      !std::isfinite(speed_steps_s) || !std::isfinite(acceleration_steps_s2)) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("axis {}: speed {:g} and acceleration {:g} must be positive",
                                 axis + 1, speed_steps_s, acceleration_steps_s2));
  }
  if (motion_[static_cast<std::size_t>(axis)].active) {
    return makeError(ErrorCode::kInvalidArgument, "cannot change the profile while moving",
                     "moving");
  }
  axes_[static_cast<std::size_t>(axis)].speed_steps_s = speed_steps_s;
  axes_[static_cast<std::size_t>(axis)].acceleration_steps_s2 = acceleration_steps_s2;
  return Ok{};
}

Status SimulatedController::placeAt(const Steps& position) {
  if (std::any_of(motion_.begin(), motion_.end(), [](const Motion& m) { return m.active; })) {
    return makeError(ErrorCode::kInvalidArgument, "cannot place the axes while moving", "moving");
  }
  for (std::size_t a = 0; a < 3; ++a)
    rest_[a] = static_cast<double>(position.motor[a]);
  return Ok{};
}

void SimulatedController::advanceTo(double time_s) {
  now_s_ = std::max(now_s_, time_s);
}

void SimulatedController::inject(InjectedFault fault, int axis) {
  injected_ = fault;
  injected_axis_ = std::clamp(axis, 0, 2);
}

}  // namespace ignav::actuation
