// Polylines as the compensation module compares them (a predicted needle path with a measured
// one): internal to the module.
#pragma once

#include <algorithm>
#include <vector>

#include <Eigen/Core>

namespace ignav::compensation::detail {

inline double polylineLength(const std::vector<Eigen::Vector3d>& line) {
  double out = 0.0;
  for (std::size_t i = 1; i < line.size(); ++i)
    out += (line[i] - line[i - 1]).norm();
  return out;
}

// The point of the polyline (not empty) nearest q.
inline Eigen::Vector3d nearestOnPolyline(const std::vector<Eigen::Vector3d>& line,
                                         const Eigen::Vector3d& q) {
  Eigen::Vector3d best = line.front();
  for (std::size_t i = 1; i < line.size(); ++i) {
    const Eigen::Vector3d a = line[i - 1], ab = line[i] - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((q - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    const Eigen::Vector3d p = a + t * ab;
    if ((p - q).squaredNorm() < (best - q).squaredNorm()) best = p;
  }
  return best;
}

// The path's points about every `spacing_mm` of arc, counted from its last point (the tip, kept),
// in the path's order.
inline std::vector<Eigen::Vector3d> thinnedFromTip(const std::vector<Eigen::Vector3d>& path,
                                                   double spacing_mm) {
  if (path.empty()) return {};
  std::vector<Eigen::Vector3d> kept{path.back()};
  double along = 0.0;
  for (std::size_t i = path.size() - 1; i-- > 0;) {
    along += (path[i + 1] - path[i]).norm();
    if (along >= spacing_mm) {
      kept.push_back(path[i]);
      along = 0.0;
    }
  }
  return {kept.rbegin(), kept.rend()};
}

}  // namespace ignav::compensation::detail
