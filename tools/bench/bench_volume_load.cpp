// Loads a DICOM series N times with ignav's reader alone (no CLI, no other libraries) and
// prints the median wall time, MB/s and the peak RSS. Used by bench_volume_load.sh.
//   bench_volume_load SERIES_DIR [runs=5] [threads=0: every core, at most 8]
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "ignav/volume/dicom.hpp"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_volume_load SERIES_DIR [runs=5] [threads=0]\n");
    return 2;
  }
  const std::string dir = argv[1];
  const int runs = argc > 2 ? std::max(1, std::atoi(argv[2])) : 5;
  const int threads = argc > 3 ? std::max(0, std::atoi(argv[3])) : 0;
  std::uintmax_t bytes = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    bytes += e.file_size();
  std::vector<double> secs, scan_secs;
  std::size_t voxel_bytes = 0;
  for (int r = 0; r < runs; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    auto scan_end = t0;
    ignav::volume::DicomLoadOptions options;
    options.threads = threads;
    options.progress = [&](const ignav::volume::Progress& p) {
      if (p.stage == "scan") scan_end = std::chrono::steady_clock::now();
    };
    const auto loaded = ignav::volume::readDicomSeries({dir}, options);
    const auto t1 = std::chrono::steady_clock::now();
    if (!loaded) {
      std::fprintf(stderr, "%s\n", loaded.error().message.c_str());
      return 1;
    }
    voxel_bytes = loaded->volume.voxels.size() * sizeof(std::int16_t);
    secs.push_back(std::chrono::duration<double>(t1 - t0).count());
    scan_secs.push_back(std::chrono::duration<double>(scan_end - t0).count());
  }
  std::sort(secs.begin(), secs.end());
  std::sort(scan_secs.begin(), scan_secs.end());
  const double median = secs[secs.size() / 2];
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const double rss_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;
  std::printf(
      "%-10s median %6.3f s  %7.0f MB/s  peak RSS %5.0f MB (%.2f x voxel bytes); "
      "header scan %.3f s of it\n",
      "ignav", median, static_cast<double>(bytes) / median / 1e6, rss_mb,
      rss_mb * 1024.0 * 1024.0 / static_cast<double>(voxel_bytes), scan_secs[scan_secs.size() / 2]);
  return 0;
}
