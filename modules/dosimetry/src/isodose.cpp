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
  const Eigen::Vector3d ijk = grid.toIjk(lps_mm);
  const auto& n = grid.dims;
  int i0[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    const double x = ijk[a];
    if (!(x >= 0.0) || x > n[static_cast<std::size_t>(a)] - 1) {
      return std::numeric_limits<double>::quiet_NaN();
    }
    // The last voxel centre interpolates with itself.
    i0[a] = std::min(static_cast<int>(x), std::max(n[static_cast<std::size_t>(a)] - 2, 0));
    f[a] = n[static_cast<std::size_t>(a)] > 1 ? x - i0[a] : 0.0;
  }
  const auto at = [&](int di, int dj, int dk) {
    const auto idx = (static_cast<std::size_t>(std::min(i0[2] + dk, n[2] - 1)) * n[1] +
                      static_cast<std::size_t>(std::min(i0[1] + dj, n[1] - 1))) *
                         n[0] +
                     static_cast<std::size_t>(std::min(i0[0] + di, n[0] - 1));
    return static_cast<double>(dose_Gy[idx]);
  };
  double sum = 0.0;
  for (int c = 0; c < 8; ++c) {
    const int di = c & 1, dj = (c >> 1) & 1, dk = (c >> 2) & 1;
    const double w = (di ? f[0] : 1.0 - f[0]) * (dj ? f[1] : 1.0 - f[1]) * (dk ? f[2] : 1.0 - f[2]);
    if (w != 0.0) sum += w * at(di, dj, dk);
  }
  return sum;
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
