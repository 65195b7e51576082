// Commands answered while the patient's structures load (issue 41; tools/bench/bench_structures.sh
// starts the server): a 512 x 512 x 300 CT (0.7 x 0.7 x 1.0 mm) and a Slicer segmentation of five
// structures on it are written, the CT is loaded, then `load_structures` runs ROUNDS times (each:
// the .seg.nrrd read and checked on the CT, a distance field per structure, on the job thread)
// while a second client sends `ping` every 5 ms. Prints the load's duration and the pings' median,
// p95, p99 and worst in milliseconds, during the loads and idle before.
//   bench_structures DOMAIN DDS_CONFIG_XML WORK_DIR [ROUNDS]
#include <cstdio>
#include <string>

#include "bench_support.hpp"
#include "ignav/volume/image_io.hpp"
#include "prostate_shapes.hpp"

namespace {

using ignav::bench::Clock;
using ignav::bench::sinceMs;
using nlohmann::json;
using namespace std::chrono_literals;

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: bench_structures DOMAIN DDS_CONFIG_XML WORK_DIR [ROUNDS]\n");
    return 2;
  }
  const auto domain = static_cast<std::uint32_t>(std::stoul(argv[1]));
  const std::string xml = ignav::protocol::readConfigFile(argv[2]);
  const std::string dir = argv[3];
  const int rounds = argc > 4 ? std::stoi(argv[4]) : 10;

  // The CT (soft tissue, HU 40) and its segmentation, written once.
  const std::string ct_path = dir + "/ct.nrrd", seg_path = dir + "/anatomy.seg.nrrd";
  ignav::volume::Volume ct;
  ct.geometry = ignav::bench::prostateCtGrid();
  ct.voxels.assign(ct.geometry.voxelCount(), 40);
  if (auto w = ignav::volume::writeNrrd(ct, ct_path, ignav::volume::NrrdEncoding::kRaw); !w.ok()) {
    std::fprintf(stderr, "%s\n", w.error().message.c_str());
    return 3;
  }
  const auto t_seg = Clock::now();
  const auto set = ignav::anatomy::voxelise(ct.geometry, Eigen::Matrix4d::Identity(),
                                            ignav::bench::prostateShapes(), seg_path);
  if (!set || !ignav::anatomy::writeSegNrrd(*set, ct.geometry, seg_path).ok()) return 4;
  std::printf("segmentation of %zu structures written in %.1f s\n", set->structures.size(),
              sinceMs(t_seg) / 1000.0);

  ignav::protocol::Client c(domain, xml, "operator", nullptr,
                            ignav::protocol::chooseRobot(domain, xml, nullptr, "", 10s));
  if (!c.waitForServer(10s)) {
    std::fprintf(stderr, "no server on domain %u\n", domain);
    return 5;
  }
  c.waitFor([](const json& s) { return s.contains("workflow"); }, 5s);
  if (!c.send("load_volume", {ct_path, {}, {}}).accepted) return 6;
  c.waitFor([](const json& s) { return s.contains("volume") && s["volume"]["status"] == "loaded"; },
            120s);

  const auto run = ignav::bench::timeJobsWhilePinging(c, domain, xml, rounds, [&] {
    return c.send("load_structures", {seg_path, {}, {}});
  });
  return ignav::bench::printJobsWhilePinging(run, "load_structures", "structure load",
                                             "structures load")
             ? 0
             : 7;
}
