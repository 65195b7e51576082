// Whether the instrument reaches a point, at a few nanoseconds a point, for drawing the feasible
// volume on every slice a viewer scrolls through (issue 28). The answer is Kinematics::inverse's,
// exactly: the tip depth at z_c = 0 is tabulated over the tip radius, and a point within the
// table's error of a limit is decided by inverse() itself.
#pragma once

#include <array>
#include <vector>

#include <Eigen/Core>

#include "ignav/kinematics/solver.hpp"

namespace ignav::kinematics {

class ReachableRegion {
 public:
  explicit ReachableRegion(const Kinematics& kinematics);

  // The same as inverse(robot_mm)->reachable(), for a finite point (non-finite: false).
  bool contains(const Eigen::Vector3d& robot_mm) const;
  // The corners of a box (robot frame, mm) that holds every reachable point.
  std::array<Eigen::Vector3d, 8> boundingBox() const;
  // How close to a depth limit contains() asks inverse(): the widest band over the radii, and the
  // share of the radius range where it is under a micrometre (for tests and the curious).
  double widestBand_mm() const;
  double tableShare() const;

 private:
  bool exactly(const Eigen::Vector3d& robot_mm) const;

  Kinematics kinematics_;
  double r_min_mm_, r_max_mm_, zc_max_mm_;
  double step_mm_ = 0.0;          // radius between table entries
  std::vector<double> depth_mm_;  // tipDepthAtHome at r_min + i * step
  std::vector<double> band_mm_;   // per interval: inverse() decides this close to a depth limit
  double depth_lo_mm_ = 0.0, depth_hi_mm_ = 0.0;
};

}  // namespace ignav::kinematics
