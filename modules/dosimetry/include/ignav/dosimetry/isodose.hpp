// Isodose lines on slices (issue 42, part 5): each level of the prescription as an outline in its
// colour, named, for the slice renderer (volume/render.hpp) — the server's slices, the report's,
// the web viewer's region overlay.
#pragma once

#include <memory>
#include <vector>

#include "ignav/volume/render.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::dosimetry {

struct IsodoseLevel {
  double percent = 100.0;  // of the prescription
  volume::Rgb colour;
};

// 50 % blue, 100 % red, 150 % yellow, 200 % white: the levels an implant is read by.
std::vector<IsodoseLevel> standardIsodoseLevels();

// One outline per level where the dose (trilinear between the grid's voxel centres) reaches it,
// named "100 %" and so on; asked only within the grid's box. `dose_Gy` is the grid's, x fastest.
std::vector<volume::RegionOverlay> isodoseOverlays(
    std::shared_ptr<const std::vector<float>> dose_Gy, const volume::Geometry& grid,
    double prescription_Gy, const std::vector<IsodoseLevel>& levels = standardIsodoseLevels());

// The dose (Gy) at an LPS point, trilinear between the grid's voxel centres; NaN outside them.
double doseAt(const std::vector<float>& dose_Gy, const volume::Geometry& grid,
              const Eigen::Vector3d& lps_mm);

}  // namespace ignav::dosimetry
