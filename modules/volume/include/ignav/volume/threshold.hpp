// The bright voxels of a CT: one vectorised pass (a block of 4096 voxels without one is skipped
// by its extreme), comparing stored int16 values, so that finding markers or seeds costs about a
// memory read of the volume. Shared by marker detection (modules/registration) and seed
// detection (modules/verification).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::volume {

// The linear indices (increasing; x fastest) of the voxels at or above `min_hu`. Errors: a value
// scale of 0 or not finite; more than `max_count` such voxels (reason "too_many_bright_voxels",
// for the caller to name its own setting).
Expected<std::vector<std::uint32_t>> voxelsAtOrAbove(const Volume& volume, double min_hu,
                                                     std::size_t max_count);

}  // namespace ignav::volume
