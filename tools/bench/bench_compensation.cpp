// Aiming with the deflection model (issue 23): one predicted landing, one compensated aim (Newton
// on the joints), and a tissue fit from 20 measured landings, on the paper's robot in agar.
//   build/tools/bench/bench_compensation --benchmark_repetitions=5
#include <benchmark/benchmark.h>

#include "ignav/compensation/compensation.hpp"
#include "ignav/config/robot_config.hpp"

namespace {

using namespace ignav;

const config::Robot& robot() {
  static const config::Robot r = config::loadRobot(IGNAV_ROBOT_CONFIG).value();
  return r;
}

compensation::DeflectionModel agar() {
  compensation::DeflectionModel m;
  m.needle = {-1.0 / 400.0, 20.0, -1};
  m.tissue = {0.49, 0.22};
  return m;
}

const Eigen::Vector3d kTarget{8.0, 12.0, -175.0};

void BM_PredictLanding(benchmark::State& state) {
  const auto joints = robot().kinematics.inverse(kTarget).value().joints;
  const auto model = agar();
  for (auto _ : state)
    benchmark::DoNotOptimize(compensation::predictLanding(robot().kinematics, model, joints));
}
BENCHMARK(BM_PredictLanding)->Unit(benchmark::kMicrosecond);

void BM_CompensateOneTarget(benchmark::State& state) {
  const auto model = agar();
  for (auto _ : state)
    benchmark::DoNotOptimize(compensation::compensate(robot().kinematics, model, kTarget));
}
BENCHMARK(BM_CompensateOneTarget)->Unit(benchmark::kMicrosecond);

void BM_FitTissueFrom20Landings(benchmark::State& state) {
  const auto model = agar();
  std::vector<compensation::TargetingRecord> records;
  for (int i = 0; i < 20; ++i) {
    const double a = 0.3 * i;
    const Eigen::Vector3d target{10.0 * std::cos(a), 10.0 * std::sin(a), -160.0 - 1.0 * i};
    const auto joints = robot().kinematics.inverse(target).value().joints;
    const auto landed = compensation::predictLanding(robot().kinematics, model, joints).value();
    records.push_back({"T" + std::to_string(i), target, joints, landed.tip_mm, {}});
  }
  compensation::DeflectionModel start = model;
  start.tissue = {0.2, 0.1};  // the fit starts elsewhere (TargetingFitOptions::initial)
  if (auto fit = compensation::fitTissueFromTargeting(robot().kinematics, start, records); !fit) {
    state.SkipWithError(fit.error().message.c_str());
    return;
  }
  for (auto _ : state)
    benchmark::DoNotOptimize(
        compensation::fitTissueFromTargeting(robot().kinematics, start, records));
}
BENCHMARK(BM_FitTissueFrom20Landings)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
