// The plane of θc (MODEL.md §2): p = Rz(θc)·(0, y′, z′). The stylet curves towards +y′; z′ is Z,
// the needle goes in along −Z. What deflection models work in, in 2-D.
#pragma once

#include <cmath>

#include <Eigen/Core>

namespace ignav::kinematics {

struct ThetaPlane {
  explicit ThetaPlane(double theta_c_rad) : u(-std::sin(theta_c_rad), std::cos(theta_c_rad), 0.0) {}
  Eigen::Vector2d in(const Eigen::Vector3d& p) const { return {p.dot(u), p.z()}; }  // (y′, z′)
  Eigen::Vector3d out(const Eigen::Vector2d& p) const {
    return {p.x() * u.x(), p.x() * u.y(), p.y()};
  }
  // v turned in the plane by turn_rad: −Z, i.e. (0, −1), goes to (sin t, −cos t), towards +y′.
  static Eigen::Vector2d turned(const Eigen::Vector2d& v, double turn_rad) {
    const double c = std::cos(turn_rad), s = std::sin(turn_rad);
    return {c * v.x() - s * v.y(), s * v.x() + c * v.y()};
  }
  Eigen::Vector3d u;  // y′
};

}  // namespace ignav::kinematics
