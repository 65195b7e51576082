// Bright voxels grouped by 26-connectivity: what seed and needle detection both start from.
// Internal to the verification module.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::verification {

struct BrightGroups {
  std::vector<std::uint32_t> bright;    // linear voxel indices at or above the threshold
  std::vector<std::uint32_t> group_of;  // per bright voxel: its group
  std::vector<std::size_t> start;       // group q's members are members[start[q] .. start[q+1])
  std::vector<std::uint32_t> members;   // positions in `bright`, scan order within a group
  std::array<int, 3> dims{};
  std::size_t count() const { return start.empty() ? 0 : start.size() - 1; }
  // The voxel (i, j, k) of members[e].
  Eigen::Vector3i voxel(std::size_t e) const;
};

// `bright`: linear voxel indices in increasing order (volume::voxelsAtOrAbove). Groups are
// numbered in the order of their first voxels.
BrightGroups groupBrightVoxels(std::vector<std::uint32_t> bright, const std::array<int, 3>& dims);

// The volume checked (geometry, buffer), thresholded at min_hu and grouped. `search` names the
// caller's settings in errors ("seed search"), `what` what min_hu should be raised towards.
Expected<BrightGroups> findBrightGroups(const volume::Volume& volume, double min_hu,
                                        std::size_t max_bright_voxels, const std::string& search,
                                        const std::string& what);

// The median (reorders the values; they must not be empty).
double medianOf(std::vector<double>& values);

}  // namespace ignav::verification
