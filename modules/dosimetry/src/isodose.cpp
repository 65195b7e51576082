// Isodose lines on slices (isodose.hpp).
#include "ignav/dosimetry/isodose.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace ignav::dosimetry {

std::vector<IsodoseLevel> standardIsodoseLevels() {
  return {{50.0, {64, 128, 255}},
          {100.0, {255, 40, 40}},
          {150.0, {255, 230, 0}},
          {200.0, {255, 255, 255}}};
}

double doseAt(const std::vector<float>& dose_Gy, const volume::Geometry& grid,
              const Eigen::Vector3d& lps_mm) {
  const auto& n = grid.dims;
  return volume::trilinear(
             n, grid.toIjk(lps_mm),
             [&](int i, int j, int k) {
               return dose_Gy[(static_cast<std::size_t>(k) * n[1] + static_cast<std::size_t>(j)) *
                                  n[0] +
                              static_cast<std::size_t>(i)];
             })
      .value_or(std::numeric_limits<double>::quiet_NaN());
}

std::vector<volume::RegionOverlay> isodoseOverlays(
    std::shared_ptr<const std::vector<float>> dose_Gy, const volume::Geometry& grid,
    double prescription_Gy, const std::vector<IsodoseLevel>& levels) {
  std::vector<Eigen::Vector3d> box;
  for (int c = 0; c < 8; ++c) {
    box.push_back(grid.toLps(Eigen::Vector3d(
        c & 1 ? grid.dims[0] - 1 : 0, c & 2 ? grid.dims[1] - 1 : 0, c & 4 ? grid.dims[2] - 1 : 0)));
  }
  std::vector<volume::RegionOverlay> out;
  for (const IsodoseLevel& level : levels) {
    const double threshold_Gy = prescription_Gy * level.percent / 100.0;
    volume::RegionOverlay r;
    r.contains = [dose_Gy, grid, threshold_Gy](const Eigen::Vector3d& lps) {
      return doseAt(*dose_Gy, grid, lps) >= threshold_Gy;  // NaN outside: false
    };
    r.bounds_lps_mm = box;
    r.colour = level.colour;
    r.opacity = 1.0;
    r.outline = true;
    r.label = fmt::format("{:g} %", level.percent);
    out.push_back(std::move(r));
  }
  return out;
}

}  // namespace ignav::dosimetry
