// Slice request -> PNG received, over DDS from a running ignav-server (tools/bench/bench_slices.sh
// starts one on a 512x512x300 series), as a viewer scrolling through the feasible region asks:
// axial 512² at 0.2 mm/px, the centre moving 0.5 mm along the slice normal at every request.
//   plain     : the CT alone (overlays off)
//   region    : with the feasible region tinted (region_only)
//   overlays  : the region, fiducials and targets (what the viewers ask)
//   anchor    : the same reslice done in this client from the same series, then libpng's
//               defaults (png_image_write_to_memory, grey): what a client pays to do it itself
// The four run interleaved, round by round. Prints median, p95 and p99 in ms, and PNG bytes.
//   bench_slices DOMAIN DDS_CONFIG_XML SERIES_DIR [ROUNDS]
#include <png.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include <Eigen/LU>

#include "bench_support.hpp"
#include "ignav/protocol/client.hpp"
#include "ignav/volume/dicom.hpp"
#include "ignav/volume/render.hpp"
#include "ignav/volume/slice.hpp"

namespace {

using ignav::bench::Clock;
using ignav::bench::percentile;
using ignav::bench::sinceMs;
using nlohmann::json;

// The client doing it itself: reslice, window to grey, libpng's simplified API with its defaults.
std::size_t resliceAndEncode(const ignav::volume::Volume& ct,
                             const ignav::volume::SliceSpec& spec) {
  const auto slice = ignav::volume::reslice(ct, spec).value();
  std::vector<std::uint8_t> grey(slice.values.size());
  for (std::size_t i = 0; i < grey.size(); ++i)
    grey[i] = ignav::volume::windowGrey(slice.values[i], spec.window);  // NaN (outside): black
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(slice.width);
  image.height = static_cast<png_uint_32>(slice.height);
  image.format = PNG_FORMAT_GRAY;
  std::vector<std::uint8_t> png(grey.size() * 2 + 4096);  // ample: one pass
  png_alloc_size_t bytes = png.size();
  if (!png_image_write_to_memory(&image, png.data(), &bytes, 0, grey.data(), 0, nullptr)) return 0;
  return bytes;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: bench_slices DOMAIN DDS_CONFIG_XML SERIES_DIR [ROUNDS]\n");
    return 2;
  }
  const auto domain = static_cast<std::uint32_t>(std::stoul(argv[1]));
  const std::string xml = ignav::protocol::readConfigFile(argv[2]);
  const std::string series = argv[3];
  const int rounds = argc > 4 ? std::stoi(argv[4]) : 300;
  ignav::protocol::Client c(
      domain, xml, "operator", nullptr,
      ignav::protocol::chooseRobot(domain, xml, nullptr, "", std::chrono::seconds(10)));
  if (!c.waitForServer(std::chrono::seconds(10))) {
    std::fprintf(stderr, "no server on domain %u\n", domain);
    return 3;
  }
  if (!ignav::bench::loadAndRegister(c, series)) return 4;
  const Eigen::Matrix4d to_image =
      ignav::protocol::matrixFromState(c.state()["registration"]["image_to_robot"]).inverse();
  // Two targets in view, as a planning session has.
  for (const Eigen::Vector4d& robot :
       {Eigen::Vector4d(8, 12, -175, 1), Eigen::Vector4d(-6, 4, -170, 1)}) {
    c.send("add_target", {"", {Eigen::Vector3d((to_image * robot).head<3>())}, {}});
  }
  // Through the middle of the feasible volume, scrolling down and back 0.5 mm at a step.
  const Eigen::Vector3d mid = (to_image * Eigen::Vector4d(0, 0, -172, 1)).head<3>();
  auto centre = [&](int i) {
    const int step = i % 40 < 20 ? i % 40 : 40 - i % 40;
    return Eigen::Vector3d(mid + Eigen::Vector3d(0, 0, 0.5 * (step - 10)));
  };

  const auto ct = ignav::volume::readDicomSeries({series});
  if (!ct) {
    std::fprintf(stderr, "%s\n", ct.error().message.c_str());
    return 6;
  }
  std::map<std::string, std::vector<double>> ms;
  std::map<std::string, std::size_t> bytes;
  int failed = 0;
  auto over_dds = [&](const char* name, int i, bool overlays, bool region_only, bool keep) {
    ignav::protocol::SliceArgs s;
    s.view = "axial";
    s.centre_lps = centre(i);
    s.size_px = 512;
    s.pixel_mm = 0.2;
    s.overlays = overlays;
    s.region_only = region_only;
    const auto t = Clock::now();
    const auto r = c.slice(s, std::chrono::seconds(10));
    const double took = sinceMs(t);
    if (!r.ok) {
      ++failed;
      std::fprintf(stderr, "%s: %s\n", name, r.message.c_str());
      return;
    }
    if (keep) ms[name].push_back(took);
    bytes[name] = r.png.size();
  };
  auto anchor = [&](int i, bool keep) {
    ignav::volume::SliceSpec spec;
    spec.view = ignav::volume::View::kAxial;
    spec.centre_lps_mm = centre(i);
    spec.width_px = spec.height_px = 512;
    spec.pixel_size_mm = 0.2;
    spec.window = ignav::volume::kWindowBone;
    const auto t = Clock::now();
    bytes["anchor"] = resliceAndEncode(ct->volume, spec);
    if (keep) ms["anchor"].push_back(sinceMs(t));
  };
  const int warm_up = 20;
  for (int i = 0; i < warm_up + rounds; ++i) {
    const bool keep = i >= warm_up;
    over_dds("plain", i, false, false, keep);
    over_dds("region", i, true, true, keep);
    over_dds("overlays", i, true, false, keep);
    anchor(i, keep);
  }
  for (const char* name : {"plain", "region", "overlays", "anchor"}) {
    const auto& v = ms[name];
    if (v.empty()) continue;
    std::printf("%-9s median %6.2f ms   p95 %6.2f ms   p99 %6.2f ms   %4zu kB   (%zu rounds)\n",
                name, percentile(v, 50), percentile(v, 95), percentile(v, 99), bytes[name] / 1000,
                v.size());
  }
  return failed == 0 ? 0 : 1;
}
