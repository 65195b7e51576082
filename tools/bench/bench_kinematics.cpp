// Kinematics throughput: exact IK, closed-form IK, and the whole reachability map.
// Run: build/tools/bench/bench_kinematics  (figures recorded in docs/PERFORMANCE.md)
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "ignav/config/robot_config.hpp"
#include "ignav/kinematics/workspace_map.hpp"

namespace {

using ignav::kinematics::Kinematics;

const Kinematics& paperInstrument() {
  static const Kinematics k = ignav::config::loadRobot(IGNAV_ROBOT_CONFIG).value().kinematics;
  return k;
}

// Reachable targets drawn uniformly in joint space, so every solve does the full work.
std::vector<Eigen::Vector3d> reachableTargets(const Kinematics& k, size_t n) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> theta(0.0, 6.283185307179586);
  std::uniform_real_distribution<double> zc(0.0, k.instrument().cannula_travel_mm);
  std::uniform_real_distribution<double> zs(0.0, k.instrument().stylet_travel_mm);
  std::vector<Eigen::Vector3d> out;
  out.reserve(n);
  for (size_t i = 0; i < n; ++i)
    out.push_back(k.forward({theta(rng), zc(rng), zs(rng)}).tip_mm);
  return out;
}

void BM_InverseExact(benchmark::State& state) {
  const Kinematics& k = paperInstrument();
  const auto targets = reachableTargets(k, 4096);
  size_t i = 0;
  for (auto _ : state) {
    auto s = k.inverse(targets[i++ & 4095]);
    benchmark::DoNotOptimize(s);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_InverseExact);

void BM_InverseClosedFormJointsOnly(benchmark::State& state) {
  // The closed form alone (eq 16/17) with no scoring FK: what a planner pays for the paper's IK.
  const Kinematics& k = paperInstrument();
  const auto targets = reachableTargets(k, 4096);
  size_t i = 0;
  for (auto _ : state) {
    auto joints = k.closedFormJoints(targets[i++ & 4095]);
    benchmark::DoNotOptimize(joints);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
}
BENCHMARK(BM_InverseClosedFormJointsOnly);

void BM_WorkspaceMap(benchmark::State& state) {
  const Kinematics& k = paperInstrument();
  const double grid_mm = static_cast<double>(state.range(0)) / 100.0;
  size_t points = 0;
  for (auto _ : state) {
    auto map = ignav::kinematics::computeWorkspaceMap(k, grid_mm);
    points = map->points_mm.size();
    benchmark::DoNotOptimize(map);
  }
  state.counters["points"] = static_cast<double>(points);
}
BENCHMARK(BM_WorkspaceMap)->Arg(50)->Arg(25)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
