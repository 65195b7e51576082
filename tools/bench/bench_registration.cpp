// Registration throughput: the 3-point fit, a TRE estimate, and fiducial detection on the
// built-in robot phantom (128×128×112 CT) and on a clinical-size 512×512×300 grid.
// Run: build/tools/bench/bench_registration  (figures recorded in docs/PERFORMANCE.md)
#include <benchmark/benchmark.h>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/fiducial_detection.hpp"
#include "ignav/registration/point_registration.hpp"
#include "ignav/registration/robot_phantom.hpp"

namespace {

using namespace ignav;

const config::Robot& robot() {
  static const config::Robot r = config::loadRobot(IGNAV_ROBOT_CONFIG).value();
  return r;
}

std::vector<Eigen::Vector3d> model() {
  return {robot().feature_points_mm.begin(), robot().feature_points_mm.end()};
}

void BM_RegisterThreePoints(benchmark::State& state) {
  const auto robot_points = model();
  std::vector<Eigen::Vector3d> image;
  for (const auto& p : robot_points)
    image.push_back(p + Eigen::Vector3d(0.1, -0.2, 0.05));
  for (auto _ : state) {
    auto r = registration::registerPoints(image, robot_points,
                                          registration::TransformKind::kSimilarity, {});
    benchmark::DoNotOptimize(r);
  }
}
BENCHMARK(BM_RegisterThreePoints);

void BM_ExpectedTre(benchmark::State& state) {
  const auto config = registration::describeFiducials(model());
  const Eigen::Vector3d target(5, 10, -180);
  for (auto _ : state) {
    benchmark::DoNotOptimize(registration::expectedTre_mm(
        config, target, 0.5, registration::TransformKind::kSimilarity));
  }
}
BENCHMARK(BM_ExpectedTre);

volume::Volume robotPhantom(std::array<int, 3> dims, Eigen::Vector3d spacing) {
  auto rp =
      registration::makeRobotPhantom(robot().kinematics, robot().config.registration.scan).value();
  rp.spec.dims = dims;
  rp.spec.spacing_mm = spacing;
  rp.spec.noise_sigma_hu = 10.0;
  return volume::makePhantom(rp.spec).value();
}

void BM_FindFiducials(benchmark::State& state, std::array<int, 3> dims, Eigen::Vector3d spacing) {
  const auto v = robotPhantom(dims, spacing);
  const auto m = model();
  for (auto _ : state) {
    auto d = registration::findFiducials(v, {}, m);
    if (!d || !d->match) state.SkipWithError("no match");
    benchmark::DoNotOptimize(d);
  }
  state.counters["voxels"] = static_cast<double>(v.voxels.size());
}
BENCHMARK_CAPTURE(BM_FindFiducials, robot_phantom_128x128x112, {128, 128, 112},
                  Eigen::Vector3d(0.8, 0.8, 1.25))
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_FindFiducials, clinical_512x512x300, {512, 512, 300},
                  Eigen::Vector3d(0.25, 0.25, 0.5))
    ->Unit(benchmark::kMillisecond);

// Clustering cost grows with the bright voxels: a threshold that catches 10^5 voxels.
void BM_ClusterManyBrightVoxels(benchmark::State& state) {
  auto v = robotPhantom({128, 128, 112}, Eigen::Vector3d(0.8, 0.8, 1.25));
  registration::FiducialSearch search;
  search.min_hu = 2.0e4;  // above everything, then paint a slab of bright voxels
  const int slabs = static_cast<int>(state.range(0));
  for (int k = 0; k < slabs; ++k) {
    for (int j = 0; j < 128; ++j) {
      for (int i = 0; i < 128; ++i)
        v.voxels[v.index(i, j, 10 + 2 * k)] = 25000;
    }
  }
  for (auto _ : state) {
    auto d = registration::findFiducials(v, search, {});
    benchmark::DoNotOptimize(d);
  }
  state.counters["bright_voxels"] = 128.0 * 128.0 * slabs;
}
BENCHMARK(BM_ClusterManyBrightVoxels)->Arg(1)->Arg(6)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
