// What the seeds deliver (issue 42): the TG-43U1 dose rate of 100 I-125 seeds at every voxel of a
// 1 mm grid over a 60 mm cube (61³ voxels), on one thread and on two, and the seed model's table
// made once. Google Benchmark; docs/PERFORMANCE.md has the figures.
#include <benchmark/benchmark.h>

#include <random>

#include "ignav/dosimetry/dose_grid.hpp"

namespace {

using namespace ignav::dosimetry;

const DoseRateTable& table() {
  static const DoseRateTable t =
      DoseRateTable::make(readSeedModel(IGNAV_SOURCE_DIR "/configs/seeds/oncura_6711.yaml").value())
          .value();
  return t;
}

// 100 seeds in the cube's middle 40 mm, along needles tilted up to ~15° from the cube's z axis.
std::vector<Seed> hundredSeeds() {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> where(-20.0, 20.0), tilt(-0.25, 0.25);
  std::vector<Seed> seeds;
  for (int n = 0; n < 100; ++n)
    seeds.push_back({{where(rng), where(rng), where(rng)},
                     Eigen::Vector3d(tilt(rng), tilt(rng), 1.0).normalized()});
  return seeds;
}

ignav::volume::Geometry cube() {
  ignav::volume::Geometry g;
  g.dims = {61, 61, 61};
  g.spacing_mm = Eigen::Vector3d::Ones();
  g.origin_lps_mm = Eigen::Vector3d::Constant(-30.0);
  return g;
}

void BM_DoseRate100SeedsOn60mmCube(benchmark::State& state) {
  const auto seeds = hundredSeeds();
  const auto grid = cube();
  const auto threads = static_cast<unsigned>(state.range(0));
  for (auto _ : state)
    benchmark::DoNotOptimize(doseRateOnGrid(table(), seeds, 0.5, grid, threads));
  state.SetLabel(std::to_string(grid.voxelCount()) + " voxels x 100 seeds, " +
                 std::to_string(threads) + " thread(s)");
}
BENCHMARK(BM_DoseRate100SeedsOn60mmCube)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_DoseRateTableOfASeedModel(benchmark::State& state) {
  const SeedModel model = readSeedModel(IGNAV_SOURCE_DIR "/configs/seeds/oncura_6711.yaml").value();
  for (auto _ : state)
    benchmark::DoNotOptimize(DoseRateTable::make(model));
}
BENCHMARK(BM_DoseRateTableOfASeedModel)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
