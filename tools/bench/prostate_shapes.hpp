// A prostate CT's five structures for the anatomy benches (bench_anatomy, bench_structures): a
// 512 x 512 x 300 grid of 0.7 x 0.7 x 1.0 mm, and a prostate, its urethra, the rectum behind, the
// bladder above and the pubic arch in front as signed distances (LPS, mm).
#pragma once

#include <algorithm>
#include <vector>

#include "ignav/anatomy/structures.hpp"

namespace ignav::bench {

inline volume::Geometry prostateCtGrid() {
  volume::Geometry g;
  g.dims = {512, 512, 300};
  g.spacing_mm = Eigen::Vector3d(0.7, 0.7, 1.0);
  g.origin_lps_mm = Eigen::Vector3d(-179.0, -179.0, -150.0);
  return g;
}

inline double capsule(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                      double r) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - a - t * ab).norm() - r;
}

// A prostate, its urethra, the rectum behind, the bladder above and the pubic arch in front.
inline const std::vector<anatomy::Shape>& prostateShapes() {
  static const std::vector<anatomy::Shape> shapes = {
      {"prostate",
       {0.85, 0.6, 0.4},
       anatomy::Role::kTarget,
       0.0,
       [](const Eigen::Vector3d& p) {
         return ((p.array() / Eigen::Array3d(22.0, 17.0, 20.0)).matrix().norm() - 1.0) * 17.0;
       }},
      {"urethra",
       {1.0, 0.9, 0.2},
       anatomy::Role::kAvoid,
       3.0,
       [](const Eigen::Vector3d& p) {
         return capsule(p, {0, -3, -40}, {0, -3, 40}, 3.0);
       }},
      {"rectum",
       {0.6, 0.35, 0.25},
       anatomy::Role::kAvoid,
       5.0,
       [](const Eigen::Vector3d& p) {
         return capsule(p, {0, 30, -50}, {0, 30, 30}, 12.0);
       }},
      {"bladder",
       {0.9, 0.9, 0.5},
       anatomy::Role::kAvoid,
       3.0,
       [](const Eigen::Vector3d& p) { return (p - Eigen::Vector3d(0, 0, 50)).norm() - 25.0; }},
      {"pubic_arch",
       {0.95, 0.95, 0.85},
       anatomy::Role::kAvoid,
       2.0,
       [](const Eigen::Vector3d& p) {
         return capsule(p, {-35, -30, 25}, {35, -30, 25}, 6.0);
       }},
  };
  return shapes;
}

}  // namespace ignav::bench
