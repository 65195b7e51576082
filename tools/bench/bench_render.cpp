// Slice rendering as the server does it for a viewer: reslice 512² from a CT and encode the PNG.
//   build/tools/bench/bench_render [--benchmark_repetitions=5 --benchmark_report_aggregates_only]
// The volume is the built-in phantom with noise, at the demo's grid (128 x 128 x 112) and at a
// clinical one (512 x 512 x 300), so the PNG compresses as a real CT slice does.
#include <benchmark/benchmark.h>

#include <map>
#include <string>

#include "ignav/volume/phantom.hpp"
#include "ignav/volume/render.hpp"
#include "ignav/volume/slice.hpp"

namespace {

using namespace ignav::volume;

const Volume& phantom(int n, int slices) {
  static std::map<int, Volume> cache;
  auto it = cache.find(n);
  if (it == cache.end()) {
    PhantomSpec spec;
    spec.dims = {n, n, slices};
    spec.spacing_mm = Eigen::Vector3d(102.4 / n, 102.4 / n, 140.0 / slices);
    spec.box_half_extent_mm = Eigen::Vector3d(46.0, 46.0, 64.0);
    spec.noise_sigma_hu = 8.0;
    it = cache.emplace(n, makePhantom(spec).value()).first;
  }
  return it->second;
}

Slice axial512(const Volume& v) {
  SliceSpec spec;
  spec.view = View::kAxial;
  spec.centre_lps_mm = Eigen::Vector3d(3.0, -2.0, 5.0);
  spec.width_px = spec.height_px = 512;
  spec.pixel_size_mm = 0.2;
  return reslice(v, spec).value();
}

void BM_Reslice512(benchmark::State& state) {
  const Volume& v = phantom(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  for (auto _ : state)
    benchmark::DoNotOptimize(axial512(v));
}
BENCHMARK(BM_Reslice512)->Args({128, 112})->Args({512, 300})->Unit(benchmark::kMillisecond);

void BM_RenderPng512(benchmark::State& state) {
  const Slice slice =
      axial512(phantom(static_cast<int>(state.range(0)), static_cast<int>(state.range(1))));
  std::size_t bytes = 0;
  SliceRenderer renderer;  // as the server's slices thread keeps one
  for (auto _ : state) {
    auto png = renderer.renderPng(slice);
    bytes = png.value().size();
    benchmark::DoNotOptimize(png);
  }
  state.counters["png_kB"] = static_cast<double>(bytes) / 1000.0;
}
BENCHMARK(BM_RenderPng512)->Args({128, 112})->Args({512, 300})->Unit(benchmark::kMillisecond);

// The load bench's slice (docs/RELIABILITY.md): 128 px across the phantom with the overlays a
// viewer asks for, here 100 labelled targets (a full insertion's worth) scattered through it,
// plus the scale bar and orientation labels. The labels were most of the server's allocations.
void BM_RenderLabelled128(benchmark::State& state) {
  SliceSpec spec;
  spec.view = View::kAxial;
  spec.centre_lps_mm = Eigen::Vector3d(3.0, -2.0, 5.0);
  spec.width_px = spec.height_px = 128;
  spec.pixel_size_mm = 0.8;
  const Slice slice = reslice(phantom(128, 112), spec).value();
  Overlays overlays;
  for (int i = 0; i < 100; ++i) {
    PointMarker target;
    target.lps_mm = Eigen::Vector3d(-40.0 + 8.0 * (i % 10), -40.0 + 8.0 * (i / 10), 5.0 + i % 7);
    target.label = "T" + std::to_string(i + 1);
    overlays.points.push_back(target);
  }
  SliceRenderer renderer;
  for (auto _ : state)
    benchmark::DoNotOptimize(renderer.renderPng(slice, overlays));
}
BENCHMARK(BM_RenderLabelled128)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
