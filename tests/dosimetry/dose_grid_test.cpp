// Dose rate from many seeds on a grid (issue 42, part 1): the tabulated formalism against the
// formalism itself, and the grid's sum against a voxel-by-voxel sum made here with the grid's own
// geometry (voxel centres through Geometry::toLps, distances with Eigen).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Geometry>

#include "ignav/dosimetry/dose_grid.hpp"

namespace ignav::dosimetry {
namespace {

SeedModel i125() {
  return readSeedModel(IGNAV_SOURCE_DIR "/configs/seeds/oncura_6711.yaml").value();
}

TEST(DoseGrid, TheTableReadsAsTheFormalismToAPercentNearTheSeedAndATenthFarther) {
  const auto table = DoseRateTable::make(i125());
  ASSERT_TRUE(table.ok()) << table.error().message;
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> radius(2.0, 118.0), angle(0.0, M_PI);
  // The worst relative error by distance: the bilinear steps of 0.1 mm show most near the seed's
  // axis (F's steep first degrees, the line's end), and fade as 1/r².
  double near = 0.0, mid = 0.0, far = 0.0;
  for (int n = 0; n < 20000; ++n) {
    const double r = radius(rng), t = angle(rng);
    const double along = r * std::cos(t), away = r * std::sin(t);
    const double e =
        std::abs(table->perUnitStrength(along, away) / table->exact(along, away) - 1.0);
    double& band = r < 5.0 ? near : r < 10.0 ? mid : far;
    band = std::max(band, e);
  }
  EXPECT_LT(near, 0.015) << near;  // 2-5 mm
  EXPECT_LT(mid, 0.006) << mid;    // 5-10 mm
  EXPECT_LT(far, 0.003) << far;    // 10-118 mm
  // At the reference point, Λ; beyond the table, the formalism itself.
  EXPECT_NEAR(table->perUnitStrength(0.0, 10.0), 0.965, 1e-6);
  EXPECT_DOUBLE_EQ(table->perUnitStrength(130.0, 10.0), table->exact(130.0, 10.0));
  // Nearer than the first tabulated distance (1 mm; half the active length is 1.5 mm): the rate
  // at 1.5 mm in the same direction, finite on the seed itself.
  EXPECT_DOUBLE_EQ(table->exact(0.0, 0.5), table->exact(0.0, 1.501));
  EXPECT_TRUE(std::isfinite(table->exact(0.0, 0.0)));
}

TEST(DoseGrid, TheGridIsTheSumOverSeedsAtEveryVoxelCentre) {
  const auto table = DoseRateTable::make(i125());
  ASSERT_TRUE(table.ok());
  volume::Geometry grid;  // an oblique grid, anisotropic voxels
  grid.dims = {21, 17, 13};
  grid.spacing_mm = Eigen::Vector3d(1.5, 2.0, 2.5);
  grid.origin_lps_mm = Eigen::Vector3d(-14, -16, -15);
  grid.direction = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const std::vector<Seed> seeds = {{{0, 0, 0}, {0, 0, 1}},
                                   {{5.3, -2.1, 4.4}, Eigen::Vector3d(1, 0, 1).normalized()},
                                   {{-6, 7, -3}, Eigen::Vector3d(0.2, -1, 0.1).normalized()}};
  const double strength_U = 0.5;
  const auto rates = doseRateOnGrid(*table, seeds, strength_U, grid);
  ASSERT_EQ(rates.size(), grid.voxelCount());
  double worst = 0.0;
  int compared = 0;
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i) {
        const Eigen::Vector3d p = grid.toLps(Eigen::Vector3d(i, j, k));
        double expected = 0.0, nearest = 1e9;
        for (const Seed& s : seeds) {
          const Eigen::Vector3d d = p - s.centre_lps_mm;
          const double along = d.dot(s.axis_lps);
          expected += strength_U * table->exact(along, (d - along * s.axis_lps).norm());
          nearest = std::min(nearest, d.norm());
        }
        if (nearest < 5.0) continue;  // nearer, the table's steps show more (the test above)
        const std::size_t v = (static_cast<std::size_t>(k) * grid.dims[1] + j) * grid.dims[0] +
                              static_cast<std::size_t>(i);
        worst = std::max(worst, std::abs(rates[v] / expected - 1.0));
        ++compared;
      }
  EXPECT_GT(compared, 3500);
  EXPECT_LT(worst, 0.005) << worst;
  // Split over threads: the same numbers, voxel for voxel.
  EXPECT_EQ(doseRateOnGrid(*table, seeds, strength_U, grid, 3), rates);
}

TEST(DoseGrid, BadTablesAreRefused) {
  EXPECT_EQ(DoseRateTable::make(i125(), 0.0).error().reason, "bad_table");
  EXPECT_EQ(DoseRateTable::make(i125(), 0.1, 1000.0).error().reason, "bad_table");
  SeedModel broken = i125();
  broken.radial_g.pop_back();
  EXPECT_EQ(DoseRateTable::make(broken).error().reason, "bad_seed_model");
}

}  // namespace
}  // namespace ignav::dosimetry
