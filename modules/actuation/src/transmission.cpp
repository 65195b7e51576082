#include "ignav/actuation/transmission.hpp"

#include <cmath>
#include <sstream>

#include <Eigen/LU>

namespace ignav::actuation {
namespace {

constexpr double kRadToDeg = 57.295779513082320876798;

Eigen::Vector3d jointVector(const Joints& j) {
  return {j.theta_c_rad * kRadToDeg, j.z_c_mm, j.z_s_mm};
}

Joints fromVector(const Eigen::Vector3d& v) {
  return Joints{v[0] / kRadToDeg, v[1], v[2]};
}

}  // namespace

const char* toString(Coupling coupling) {
  return coupling == Coupling::kCarried ? "carried" : "casing";
}

Transmission::Transmission(const TransmissionSpec& spec, const Eigen::Matrix3d& m)
    : spec_(spec), steps_per_joint_(m), joint_per_step_(m.inverse()) {
  const double motor_steps_per_rev = 360.0 / spec.motor_step_deg * spec.microsteps;
  cannula_steps_per_rev_ = motor_steps_per_rev * spec.gearhead_ratio * spec.cannula_gear_ratio;
  stylet_steps_per_rev_ = motor_steps_per_rev * spec.gearhead_ratio * spec.stylet_gear_ratio;
}

Expected<Transmission> Transmission::create(const TransmissionSpec& s) {
  struct Field {
    const char* key;
    double value;
  };
  const Field fields[] = {
      {"robot.transmission.motor_step_deg", s.motor_step_deg},
      {"robot.transmission.gearhead_ratio", s.gearhead_ratio},
      {"robot.transmission.cannula_gear_ratio", s.cannula_gear_ratio},
      {"robot.transmission.stylet_gear_ratio", s.stylet_gear_ratio},
      {"robot.transmission.lead_mm", s.lead_mm},
  };
  for (const Field& f : fields) {
    if (!std::isfinite(f.value) || f.value <= 0.0) {
      std::ostringstream m;
      m << f.key << ": must be a finite positive number (got " << f.value << ")";
      return makeError(ErrorCode::kConfig, m.str());
    }
  }
  if (s.motor_step_deg > 360.0) {
    return makeError(ErrorCode::kConfig, "robot.transmission.motor_step_deg: must be <= 360");
  }
  if (s.microsteps < 1 || s.microsteps > 256) {
    return makeError(ErrorCode::kConfig,
                     "robot.transmission.microsteps: must be in [1, 256] (got " +
                         std::to_string(s.microsteps) + ")");
  }
  const double motor_per_rev = 360.0 / s.motor_step_deg * s.microsteps;
  const double kc_deg = motor_per_rev * s.gearhead_ratio * s.cannula_gear_ratio / 360.0;
  const double ks_deg = motor_per_rev * s.gearhead_ratio * s.stylet_gear_ratio / 360.0;
  const double kc_mm = kc_deg * 360.0 / s.lead_mm;
  const double ks_mm = ks_deg * 360.0 / s.lead_mm;
  // φ2 = θc (spline), φ1 = θc + 360 zc/p (thread), and the stylet nut either fixed in the casing
  // (φ3 = θc + 360 (zc + zs)/p, the stylet screw turns with the spline) or carried (φ3 ∝ zs).
  Eigen::Matrix3d m;
  m << kc_deg, kc_mm, 0.0,  //
      kc_deg, 0.0, 0.0,     //
      ks_deg, ks_mm, ks_mm;
  if (s.coupling == Coupling::kCarried) m.row(2) << 0.0, 0.0, ks_mm;
  return Transmission(s, m);
}

StepConversion Transmission::toSteps(const Joints& joints) const {
  // Quantise motor by motor in the order the coupling is triangular in (spline nut: θc only;
  // screw nut: θc, zc; stylet nut: all three), each against what the previous motors actually
  // achieve. Each joint then misses by at most half of its own step, instead of the stylet
  // collecting the cannula motors' rounding as well (up to 2.6 µm with plain rounding).
  const Eigen::Matrix3d& m = steps_per_joint_;
  const Eigen::Vector3d q = jointVector(joints);
  const double n2 = std::round(m(1, 0) * q[0]);  // half away from zero
  const double theta_deg = n2 / m(1, 0);
  const double n1 = std::round(m(0, 0) * theta_deg + m(0, 1) * q[1]);
  const double zc = (n1 - m(0, 0) * theta_deg) / m(0, 1);
  const double n3 = std::round(m(2, 0) * theta_deg + m(2, 1) * zc + m(2, 2) * q[2]);
  const double zs = (n3 - m(2, 0) * theta_deg - m(2, 1) * zc) / m(2, 2);
  StepConversion out;
  out.steps.motor = {static_cast<std::int64_t>(n1), static_cast<std::int64_t>(n2),
                     static_cast<std::int64_t>(n3)};
  out.achieved = fromVector({theta_deg, zc, zs});
  out.residual = Joints{out.achieved.theta_c_rad - joints.theta_c_rad,
                        out.achieved.z_c_mm - joints.z_c_mm, out.achieved.z_s_mm - joints.z_s_mm};
  return out;
}

Joints Transmission::toJoints(const Steps& steps) const {
  const Eigen::Vector3d n(static_cast<double>(steps.motor[0]), static_cast<double>(steps.motor[1]),
                          static_cast<double>(steps.motor[2]));
  return fromVector(joint_per_step_ * n);
}

StepConversion Transmission::move(const Joints& from, const Joints& to) const {
  const StepConversion a = toSteps(from);
  StepConversion b = toSteps(to);
  for (size_t i = 0; i < 3; ++i)
    b.steps.motor[i] -= a.steps.motor[i];
  return b;
}

}  // namespace ignav::actuation
