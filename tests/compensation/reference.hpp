// An independent reference for the deflected landing point (docs/COMPENSATION.md): the extended
// bicycle model integrated by a fixed-step classical Runge–Kutta (not the module's error-controlled
// RKF78), and the stylet turned with Eigen::AngleAxis about the normal of the plane of θc (not the
// module's planar rotation).
#pragma once

#include <cmath>

#include <Eigen/Geometry>

#include "ignav/compensation/compensation.hpp"

namespace ignav::compensation::reference {

struct End {
  double z_mm, y_mm, gamma_rad;
};

// MODEL.md §10: dz/ds = cos γ / cos α, dy/ds = sin γ / cos α,
// dγ/ds = (k + s_slip tan α / ℓ) / (1 − 2λ1γ − λ2), α = λ1γ² + λ2γ.
inline End bicycle(const deflection::NeedleModel& n, const deflection::Tissue& t, double length_mm,
                   double step_mm = 0.01) {
  if (length_mm <= 0.0) return {0.0, 0.0, 0.0};
  const int steps = static_cast<int>(std::ceil(length_mm / step_mm));
  const double h = length_mm / steps;
  auto rate = [&](const Eigen::Vector3d& x) {
    const double g = x[2], a = t.lambda1 * g * g + t.lambda2 * g;
    return Eigen::Vector3d(std::cos(g) / std::cos(a), std::sin(g) / std::cos(a),
                           (n.curvature_per_mm + n.slip_sign * std::tan(a) / n.wheelbase_mm) /
                               (1.0 - 2.0 * t.lambda1 * g - t.lambda2));
  };
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  for (int i = 0; i < steps; ++i) {
    const Eigen::Vector3d k1 = rate(x), k2 = rate(x + h / 2 * k1), k3 = rate(x + h / 2 * k2),
                          k4 = rate(x + h * k3);
    x += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  return {x[0], x[1], x[2]};
}

// The convention in 3-D: the cannula tip moves by −y along u = (−sin θc, cos θc, 0) and rises by
// z_c − z; the stylet, from the cannula tip, turns by −γ about n = (cos θc, sin θc, 0), which
// takes −Z towards u.
inline Eigen::Vector3d landing(const kinematics::Kinematics& kin, const DeflectionModel& m,
                               const kinematics::Joints& j) {
  const auto pose = kin.forward(j);
  const End e = bicycle(m.needle, m.tissue, j.z_c_mm);
  const Eigen::Vector3d u(-std::sin(j.theta_c_rad), std::cos(j.theta_c_rad), 0.0);
  const Eigen::Vector3d n(std::cos(j.theta_c_rad), std::sin(j.theta_c_rad), 0.0);
  const double zc = std::max(0.0, j.z_c_mm);
  const Eigen::Vector3d cannula =
      pose.cannula_tip_mm - e.y_mm * u + (zc - e.z_mm) * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d stylet = pose.tip_mm - pose.cannula_tip_mm;
  if (m.carry == StyletCarry::kTranslated) return cannula + stylet;
  return cannula + Eigen::AngleAxisd(-e.gamma_rad, n) * stylet;
}

}  // namespace ignav::compensation::reference
