// Seeds whose images touch (issue 40): two seeds 3 mm apart are one 26-connected bright group when
// a few partial-volume voxels join them diagonally, although the image between them falls far
// below the metal. Such a group is cut where its intensity has a valley: the threshold is raised
// within the group until it falls apart into cores that each rise well above it, and every voxel
// goes to the core it is joined to through the brightest voxels (a watershed from the cores).
// Internal to the verification module.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

namespace ignav::verification {

struct GroupSplit {
  std::vector<std::uint32_t> part_of;  // per voxel of the group: its part, 0 .. parts − 1
  std::size_t parts = 0;
  double level_hu = 0.0;  // the threshold at which the cores first stood apart
};

// `voxels` and `values`: the group's voxels (i, j, k) and their HU; `min_hu` the threshold that
// made the group. A core counts when its peak rises at least `min_depth_hu` above the level
// (smaller bumps are noise or aliasing along one seed). None when the group has no such valley.
std::optional<GroupSplit> splitAtValleys(const std::vector<Eigen::Vector3i>& voxels,
                                         const std::vector<double>& values, double min_hu,
                                         double min_depth_hu);

}  // namespace ignav::verification
