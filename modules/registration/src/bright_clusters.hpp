// The one place PCL is compiled in this module (it is slow to compile).
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

namespace ignav::registration::detail {

// Groups points whose chains of neighbours lie within tolerance_mm of each other (PCL
// Euclidean cluster extraction). Returns point indices per cluster, largest cluster first.
std::vector<std::vector<std::size_t>> euclideanClusters(const std::vector<Eigen::Vector3f>& points,
                                                        double tolerance_mm);

}  // namespace ignav::registration::detail
