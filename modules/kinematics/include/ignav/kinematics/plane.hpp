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
  Eigen::Vector3d u;  // y′
};

}  // namespace ignav::kinematics
