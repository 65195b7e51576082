// The dose as NRRD (issue 42, part 5): 32-bit floats in Gy on the dose's grid, in LPS, for 3D
// Slicer (a scalar volume) and any NRRD reader.
#pragma once

#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::dosimetry {

// `dose_Gy` holds one value per voxel of `grid`, i fastest. Errors: a size that is not the grid's,
// a non-finite or negative dose (naming the voxel), a file that cannot be written (naming it).
Status writeDoseNrrd(const std::vector<float>& dose_Gy, const volume::Geometry& grid,
                     const std::string& path);

}  // namespace ignav::dosimetry
