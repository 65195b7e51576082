// Joint values <-> motor steps through the gear train and the screw-spline coupling
// (MODEL.md §8, docs/KINEMATICS.md). Values only; no controller here.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/kinematics/instrument.hpp"

namespace ignav::actuation {

using kinematics::Joints;

// Where the stylet nut and its motor sit (MODEL.md §8): kCasing (fixed in the casing, assumption
// A, default) or kCarried (riding on the screw-spline, assumption B).
enum class Coupling { kCasing, kCarried };

const char* toString(Coupling coupling);

struct TransmissionSpec {
  double motor_step_deg = 18.0;      // full step of each stepper
  int microsteps = 1;                // controller microstepping factor
  double gearhead_ratio = 16.0;      // planetary gearhead on every motor
  double cannula_gear_ratio = 2.0;   // spur stage to both screw-spline nuts
  double stylet_gear_ratio = 1.875;  // spur stage to the stylet nut
  double lead_mm = 1.5875;           // lead of both screws (1/16 in)
  Coupling coupling = Coupling::kCasing;
};

// Motor positions in (micro)steps: [0] cannula screw nut, [1] cannula spline nut, [2] stylet nut.
struct Steps {
  std::array<std::int64_t, 3> motor{0, 0, 0};
  friend bool operator==(const Steps& a, const Steps& b) { return a.motor == b.motor; }
  friend bool operator!=(const Steps& a, const Steps& b) { return !(a == b); }
  // A position plus an increment, per motor (where a move from `a` by `b` ends).
  friend Steps operator+(Steps a, const Steps& b) {
    for (std::size_t i = 0; i < a.motor.size(); ++i)
      a.motor[i] += b.motor[i];
    return a;
  }
};

// The result of quantising joints to whole steps, and what the quantisation costs.
struct StepConversion {
  Steps steps;
  Joints achieved;  // the joints those whole steps actually produce
  // achieved - requested, per joint (rad, mm, mm); each bounded by half of that joint's own
  // step (0.28°, 1.24 µm, 1.32 µm for the paper's transmission)
  Joints residual;
};

class Transmission {
 public:
  // Errors name the YAML key under robot.transmission.
  static Expected<Transmission> create(const TransmissionSpec& spec);

  const TransmissionSpec& spec() const { return spec_; }
  // Steps per [θc (deg), zc (mm), zs (mm)], rows are motors (MODEL.md §8).
  const Eigen::Matrix3d& coupling() const { return steps_per_joint_; }

  double cannulaStepsPerDeg() const { return cannula_steps_per_rev_ / 360.0; }
  double styletStepsPerDeg() const { return stylet_steps_per_rev_ / 360.0; }
  double cannulaStepsPerMm() const { return cannula_steps_per_rev_ / spec_.lead_mm; }
  double styletStepsPerMm() const { return stylet_steps_per_rev_ / spec_.lead_mm; }

  // Absolute joints -> absolute motor positions (rounding half away from zero). θc is taken as
  // given (not wrapped): the caller decides the rotation sense.
  StepConversion toSteps(const Joints& joints) const;
  // Feedback: absolute motor positions -> joints.
  Joints toJoints(const Steps& steps) const;
  // The step increments of a joint move; `achieved` and `residual` describe the end pose.
  // Quantising the absolute end points (not the increment) keeps rounding from accumulating
  // over a sequence of moves.
  StepConversion move(const Joints& from, const Joints& to) const;

 private:
  Transmission(const TransmissionSpec& spec, const Eigen::Matrix3d& m);

  TransmissionSpec spec_;
  double cannula_steps_per_rev_ = 0.0;
  double stylet_steps_per_rev_ = 0.0;
  Eigen::Matrix3d steps_per_joint_;
  Eigen::Matrix3d joint_per_step_;
};

}  // namespace ignav::actuation
