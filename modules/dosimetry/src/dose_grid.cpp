// Dose rate from many seeds on a voxel grid (dose_grid.hpp).
#include "ignav/dosimetry/dose_grid.hpp"

#include <algorithm>
#include <cmath>
#include <thread>

#include <fmt/format.h>

namespace ignav::dosimetry {

Expected<DoseRateTable> DoseRateTable::make(const SeedModel& model, double step_mm,
                                            double reach_mm) {
  if (auto ok = validate(model); !ok.ok()) return ok.error();
  if (!std::isfinite(step_mm) || step_mm < 0.01 || step_mm > 2.0 || !std::isfinite(reach_mm) ||
      reach_mm < 10.0 || reach_mm > 300.0 || reach_mm / step_mm > 4000.0) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("dose-rate table: step {} mm, reach {} mm (0.01-2 mm, 10-300 mm, "
                                 "at most 4000 steps)",
                                 step_mm, reach_mm),
                     "bad_table");
  }
  DoseRateTable t;
  t.model_ = model;
  t.step_mm_ = step_mm;
  t.per_step_ = 1.0 / step_mm;
  t.reach_mm_ = reach_mm;
  t.nearest_cm_ = std::max(model.radial_r_cm.front(), 0.5 * model.active_length_cm + 1e-3);
  t.n_ = static_cast<int>(std::ceil(reach_mm / step_mm)) + 1;
  t.rates_.resize(static_cast<std::size_t>(t.n_) * static_cast<std::size_t>(t.n_));
  for (int a = 0; a < t.n_; ++a)
    for (int z = 0; z < t.n_; ++z)
      t.rates_[static_cast<std::size_t>(a) * static_cast<std::size_t>(t.n_) +
               static_cast<std::size_t>(z)] = static_cast<float>(t.exact(z * step_mm, a * step_mm));
  return t;
}

double DoseRateTable::exact(double along_mm, double away_mm) const {
  double r_cm = 0.1 * std::hypot(along_mm, away_mm);
  // The direction from the seed's axis; a point at its centre takes the transverse one.
  const double theta = r_cm > 0.0 ? std::atan2(std::abs(away_mm), along_mm) : M_PI / 2;
  r_cm = std::max(r_cm, nearest_cm_);
  return doseRatePerUnitStrength(model_, r_cm, theta);
}

std::vector<float> doseRateOnGrid(const DoseRateTable& table, const std::vector<Seed>& seeds,
                                  double strength_U, const volume::Geometry& grid,
                                  unsigned threads) {
  const int nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
  std::vector<float> out(grid.voxelCount(), 0.0f);
  // Voxel centres: origin + D·diag(spacing)·(i, j, k).
  const Eigen::Matrix3d step = grid.direction * grid.spacing_mm.asDiagonal();
  const auto slices = [&](int k0, int k1) {
    for (const Seed& seed : seeds) {
      const Eigen::Vector3d axis = seed.axis_lps.normalized();
      for (int k = k0; k < k1; ++k)
        for (int j = 0; j < ny; ++j) {
          const Eigen::Vector3d row_start =
              grid.origin_lps_mm + step.col(1) * j + step.col(2) * k - seed.centre_lps_mm;
          // Along a row the offset d moves by one column c of `step`: along = d·axis changes
          // linearly and |d|² quadratically, so each voxel costs a few multiply-adds, a square
          // root and the table.
          const Eigen::Vector3d c = step.col(0);
          const double along0 = row_start.dot(axis), along_step = c.dot(axis);
          const double r2_0 = row_start.squaredNorm(), r2_1 = 2.0 * row_start.dot(c),
                       r2_2 = c.squaredNorm();
          float* dst = &out[(static_cast<std::size_t>(k) * static_cast<std::size_t>(ny) +
                             static_cast<std::size_t>(j)) *
                            static_cast<std::size_t>(nx)];
          for (int i = 0; i < nx; ++i) {
            const double along = along0 + along_step * i;
            const double r2 = r2_0 + i * (r2_1 + i * r2_2);
            const double away = std::sqrt(std::max(r2 - along * along, 0.0));
            dst[i] += static_cast<float>(strength_U * table.perUnitStrength(along, away));
          }
        }
    }
  };
  const unsigned n = std::max(1u, std::min(threads, static_cast<unsigned>(std::max(nz, 1))));
  if (n == 1) {
    slices(0, nz);
    return out;
  }
  std::vector<std::thread> workers;
  for (unsigned w = 0; w < n; ++w) {
    const int k0 = static_cast<int>(static_cast<long>(nz) * w / n);
    const int k1 = static_cast<int>(static_cast<long>(nz) * (w + 1) / n);
    workers.emplace_back(slices, k0, k1);
  }
  for (auto& w : workers)
    w.join();
  return out;
}

}  // namespace ignav::dosimetry
