// Distances to and lengths of polylines, for tests that compare a needle's centreline with the
// truth.
#pragma once

#include <algorithm>
#include <cstddef>
#include <limits>
#include <vector>

#include <Eigen/Core>

namespace ignav::test {

inline double distanceToPolyline(const std::vector<Eigen::Vector3d>& line,
                                 const Eigen::Vector3d& q) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < line.size(); ++i) {
    const Eigen::Vector3d ab = line[i] - line[i - 1];
    const double t = std::clamp((q - line[i - 1]).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (line[i - 1] + t * ab - q).norm());
  }
  return best;
}

// From point `from` on.
inline double polylineLength(const std::vector<Eigen::Vector3d>& line, std::size_t from = 0) {
  double length = 0.0;
  for (std::size_t i = from + 1; i < line.size(); ++i)
    length += (line[i] - line[i - 1]).norm();
  return length;
}

}  // namespace ignav::test
