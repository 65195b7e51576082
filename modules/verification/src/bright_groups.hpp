// Bright voxels grouped by 26-connectivity: what seed and needle detection both start from.
// Internal to the verification module.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace ignav::verification {

struct BrightGroups {
  std::vector<std::uint32_t> group_of;  // per bright voxel (in the input's order): its group
  std::vector<std::size_t> start;       // group q's members are members[start[q] .. start[q+1])
  std::vector<std::uint32_t> members;   // positions in the bright list, scan order within a group
  std::size_t count() const { return start.empty() ? 0 : start.size() - 1; }
};

// `bright`: linear voxel indices in increasing order (volume::voxelsAtOrAbove). Groups are
// numbered in the order of their first voxels.
BrightGroups groupBrightVoxels(const std::vector<std::uint32_t>& bright,
                               const std::array<int, 3>& dims);

}  // namespace ignav::verification
