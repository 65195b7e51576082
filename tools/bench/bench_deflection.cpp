// The extended bicycle model's costs: a 130 mm path, the deflection at 65 depths, and a tissue
// fit from 65 observations (with its plain-model comparison).
//   build/tools/bench/bench_deflection --benchmark_repetitions=5
#include <benchmark/benchmark.h>

#include "ignav/deflection/bicycle_model.hpp"

namespace {

using namespace ignav::deflection;

const NeedleModel kNeedle{-1.0 / 400.0, 20.0, -1};
const Tissue kAgar{0.49, 0.22};

void BM_Simulate130mm(benchmark::State& state) {
  for (auto _ : state)
    benchmark::DoNotOptimize(simulate(kNeedle, kAgar, 130.0, 1.0));
}
BENCHMARK(BM_Simulate130mm)->Unit(benchmark::kMicrosecond);

void BM_DeflectionAt65Depths(benchmark::State& state) {
  std::vector<double> depths;
  for (int i = 1; i <= 65; ++i)
    depths.push_back(2.0 * i);
  for (auto _ : state)
    benchmark::DoNotOptimize(deflectionAtDepths(kNeedle, kAgar, depths));
}
BENCHMARK(BM_DeflectionAt65Depths)->Unit(benchmark::kMicrosecond);

void BM_FitTissue65Observations(benchmark::State& state) {
  std::vector<Observation> observed;
  const auto path = simulate(kNeedle, kAgar, 130.0, 2.0).value();
  for (const auto& p : path)
    if (p.s_mm > 0) observed.push_back({p.z_mm, p.y_mm});
  for (auto _ : state)
    benchmark::DoNotOptimize(fitTissue(kNeedle, observed));
}
BENCHMARK(BM_FitTissue65Observations)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
