// The patient's structures (issue 41): distance fields for five structures of a prostate CT on a
// 512 x 512 x 300 grid (0.7 x 0.7 x 1.0 mm), one target's whole-needle clearance once they
// exist, and those five written as a DICOM RT Structure Set and read back onto the grid.
// Google Benchmark; docs/PERFORMANCE.md has the figures.
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>

#include "ignav/anatomy/clearance.hpp"
#include "ignav/anatomy/dicom_structures.hpp"
#include "prostate_shapes.hpp"

namespace {

using ignav::anatomy::DistanceField;

constexpr double kReach_mm = 15.0;  // the server's (workflow::kStructureReach_mm)

const ignav::anatomy::StructureSet& structures() {
  static const auto set =
      ignav::anatomy::voxelise(ignav::bench::prostateCtGrid(), Eigen::Matrix4d::Identity(),
                               ignav::bench::prostateShapes(), "bench")
          .value();
  return set;
}

// Every structure's field, as the server's structure load builds them.
void BM_DistanceFieldsFiveStructures(benchmark::State& state) {
  const auto& set = structures();
  std::size_t bytes = 0;
  for (auto _ : state) {
    bytes = 0;
    for (const auto& s : set.structures) {
      const auto field = DistanceField::fromMask(s.mask, kReach_mm);
      bytes += field.bytes();
      benchmark::DoNotOptimize(field);
    }
  }
  state.counters["field_MB"] = static_cast<double>(bytes) / 1e6;
}
BENCHMARK(BM_DistanceFieldsFiveStructures)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_DistanceFieldUrethra(benchmark::State& state) {
  const auto& mask = structures().structures.at(1).mask;
  for (auto _ : state)
    benchmark::DoNotOptimize(DistanceField::fromMask(mask, kReach_mm));
}
BENCHMARK(BM_DistanceFieldUrethra)->Unit(benchmark::kMillisecond);

// One target: a 100 mm cannula down to the prostate and a 30 mm stylet arc beside the urethra,
// against the four avoided structures.
void BM_ClearanceOneTarget(benchmark::State& state) {
  const auto& set = structures();
  std::vector<DistanceField> fields;
  for (std::size_t n = 1; n < set.structures.size(); ++n)
    fields.push_back(DistanceField::fromMask(set.structures[n].mask, kReach_mm));
  ignav::anatomy::NeedleBody body(2);
  for (int i = 0; i <= 200; ++i)
    body[0].centreline_lps_mm.emplace_back(8.0, -2.0, -110.0 + 0.5 * i);
  body[0].radius_mm = 1.05;
  for (int i = 0; i <= 60; ++i) {
    const double a = 0.5 * i / 35.5;
    body[1].centreline_lps_mm.emplace_back(8.0 + 35.5 * (1 - std::cos(a)), -2.0,
                                           -10.0 + 35.5 * std::sin(a));
  }
  body[1].radius_mm = 0.6;
  for (auto _ : state) {
    double closest = 1e9;
    for (const auto& f : fields)
      closest = std::min(closest, ignav::anatomy::closestApproach(body, f, 0.1).distance_mm);
    benchmark::DoNotOptimize(closest);
  }
}
BENCHMARK(BM_ClearanceOneTarget)->Unit(benchmark::kMicrosecond);

// The five as an RT Structure Set (written once, ~3 contours per structure and slice), read and
// rasterised back onto the CT's grid as load_structures does: the file parsed by DCMTK, every
// contour checked and drawn by the even-odd rule.
void BM_RtStructureSetRead(benchmark::State& state) {
  const auto path = std::filesystem::temp_directory_path() / "ignav_bench_rtstruct.dcm";
  const ignav::anatomy::CtFrame ct{ignav::bench::prostateCtGrid(), "1.2.826.0.1.3680043.10.1.1",
                                   "bench"};
  if (!ignav::anatomy::writeRtStructureSet(structures(), ct, {}, path.string()).ok()) {
    state.SkipWithError("the RT Structure Set was not written");
    return;
  }
  std::size_t voxels = 0;
  for (auto _ : state) {
    auto read = ignav::anatomy::readStructures(path.string(), ct);
    if (!read) {
      state.SkipWithError(read.error().message.c_str());
      break;
    }
    voxels = 0;
    for (const auto& s : read->structures)
      voxels += s.mask.count();
  }
  state.counters["MB"] = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
  std::size_t written = 0;
  for (const auto& s : structures().structures)
    written += s.mask.count();
  state.counters["voxels"] = static_cast<double>(voxels);
  state.counters["voxels_written"] = static_cast<double>(written);
  std::filesystem::remove(path);
}
BENCHMARK(BM_RtStructureSetRead)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
