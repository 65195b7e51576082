// Dose rate from many seeds on a voxel grid (issue 42): a seed model's TG-43U1 2D formalism
// tabulated once in along/away coordinates, then summed over the seeds at every voxel centre.
#pragma once

#include <cmath>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/dosimetry/tg43.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::dosimetry {

// A seed where it lies: its centre and the direction of its long axis (a unit vector; the
// needle's direction where it was left).
struct Seed {
  Eigen::Vector3d centre_lps_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_lps = Eigen::Vector3d::UnitZ();
};

// Ḋ/S_K of the 2D formalism on a square lattice of along (|z|) and away (y) distances, read
// bilinearly. Nearer to the seed than max(its first tabulated distance, half its active length)
// the rate is the one at that distance in the same direction (TG-43 does not describe the seed's
// inside); beyond the lattice, the formalism itself.
class DoseRateTable {
 public:
  static Expected<DoseRateTable> make(const SeedModel& model, double step_mm = 0.1,
                                      double reach_mm = 120.0);
  // cGy h⁻¹ U⁻¹ at `along_mm` from the seed's centre along its axis and `away_mm` from the axis.
  // Inline: the grid's inner loop calls it for every voxel and seed.
  double perUnitStrength(double along_mm, double away_mm) const {
    const double z = std::abs(along_mm) * per_step_, y = std::abs(away_mm) * per_step_;
    const int zi = static_cast<int>(z), yi = static_cast<int>(y);
    if (zi + 1 >= n_ || yi + 1 >= n_) return exact(along_mm, away_mm);
    const double fz = z - zi, fy = y - yi;
    const float* row = &rates_[static_cast<std::size_t>(yi) * static_cast<std::size_t>(n_) +
                               static_cast<std::size_t>(zi)];
    const float* next = row + n_;
    return (1.0 - fy) * ((1.0 - fz) * row[0] + fz * row[1]) +
           fy * ((1.0 - fz) * next[0] + fz * next[1]);
  }
  // The formalism itself with the same rule near the seed (the table's reference).
  double exact(double along_mm, double away_mm) const;
  const SeedModel& model() const { return model_; }
  double step_mm() const { return step_mm_; }
  double reach_mm() const { return reach_mm_; }

 private:
  SeedModel model_;
  double step_mm_ = 0.1, per_step_ = 10.0, reach_mm_ = 120.0, nearest_cm_ = 0.1;
  int n_ = 0;                 // lattice points per side
  std::vector<float> rates_;  // [away index * n_ + along index]
};

// The dose rate (cGy h⁻¹) at every voxel centre of `grid` from `seeds`, each of air-kerma
// strength `strength_U`; x fastest, as a Volume's voxels. `threads` > 1 splits the slices.
std::vector<float> doseRateOnGrid(const DoseRateTable& table, const std::vector<Seed>& seeds,
                                  double strength_U, const volume::Geometry& grid,
                                  unsigned threads = 1);

}  // namespace ignav::dosimetry
