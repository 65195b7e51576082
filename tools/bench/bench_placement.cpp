// Robot placement (issue 41, part 4) on the built-in phantom: its CT, its anatomy (a prostate
// with a urethra through it, a rectum, a pubic arch) and the site's limits (the approach from
// where the phantom's robot stands, 20° of tilt, 20 mm of shift). Prints the search's duration
// (median of ROUNDS), the coverage it finds, one coverage evaluation's cost, and — with
// --brute-force — the best pose of a brute-force grid (both cores) for comparison.
//   bench_placement [ROUNDS] [--brute-force TILT_DEG SHIFT_MM DEPTH_MM]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>

#include "support/placement_scene.hpp"

namespace {

void printMedian(const char* what, std::vector<double> values) {
  std::sort(values.begin(), values.end());
  std::printf("%s: median %.2f (min %.2f, max %.2f, n %zu)\n", what, values[values.size() / 2],
              values.front(), values.back(), values.size());
}

void printPose(const char* what, const ignav::placement::PlacedPose& p) {
  const auto& o = p.pose.origin_lps_mm;
  const auto a = p.pose.insertion();
  const auto& e = p.skin.entry_lps_mm;
  std::printf(
      "%s: coverage %.2f %% (%zu of %zu; %zu out of reach), tilt %.1f°, shift %.1f mm, origin "
      "(%.1f, %.1f, %.1f), axis (%.3f, %.3f, %.3f), entry (%.1f, %.1f, %.1f), %.1f mm outside "
      "the skin\n",
      what, 100.0 * p.coverage.fraction(), p.coverage.covered, p.coverage.samples,
      p.coverage.unreachable, p.tilt_deg, p.shift_mm, o.x(), o.y(), o.z(), a.x(), a.y(), a.z(),
      e.x(), e.y(), e.z(), p.skin.skin_distance_mm);
}

}  // namespace

int main(int argc, char** argv) {
  using Clock = std::chrono::steady_clock;
  const int rounds = argc > 1 ? std::stoi(argv[1]) : 3;
  auto scene = ignav::test::makePlacementScene(IGNAV_ROBOT_CONFIG);
  if (!scene) {
    std::fprintf(stderr, "%s\n", scene.error().message.c_str());
    return 3;
  }
  const auto& s = *scene;
  std::printf("target '%s': %zu search samples (%.1f mm), %zu final samples (%.1f mm)\n",
              s.target_name.c_str(), s.search.samples(), s.search.sample_mm(), s.final.samples(),
              s.final.sample_mm());

  std::vector<double> eval_ms;
  for (int n = 0; n < 5; ++n) {
    const auto t = Clock::now();
    (void)s.search.coverage(s.mounted);
    eval_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t).count());
  }
  printMedian("one coverage evaluation (search lattice), ms", eval_ms);
  const auto at_mounted = s.final.coverage(s.mounted);
  std::printf("coverage from where the phantom's robot stands: %.1f %%\n",
              100.0 * at_mounted.fraction());

  std::vector<double> search_ms;
  ignav::placement::Placement last;
  for (int n = 0; n < rounds; ++n) {
    const auto t = Clock::now();
    auto placed = ignav::placement::placeRobot(s.search, s.final, s.limits);
    search_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t).count());
    if (!placed) {
      std::fprintf(stderr, "%s\n", placed.error().message.c_str());
      return 4;
    }
    last = *placed;
  }
  printMedian("place_robot search, ms", search_ms);
  std::printf("%zu full evaluations\n", last.evaluations);
  for (const auto& p : last.poses)
    printPose("  pose", p);

  if (argc > 2 && std::strcmp(argv[2], "--brute-force") == 0 && argc > 5) {
    ignav::placement::PoseGrid grid;
    grid.tilt_step_deg = std::stod(argv[3]);
    grid.shift_step_mm = std::stod(argv[4]);
    grid.depth_step_mm = std::stod(argv[5]);
    grid.threads = 2;
    std::size_t tried = 0;
    const auto t = Clock::now();
    const auto best = ignav::placement::bruteForcePlacement(s.search, s.limits, grid, &tried);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t).count();
    std::printf("brute force: %zu poses in %.1f s (2 threads)\n", tried, ms / 1000.0);
    printPose("  best of the grid (search lattice)", best);
    const auto fine = s.final.coverage(best.pose);
    std::printf("  best of the grid on the final lattice: %.2f %%; the search's: %.2f %%\n",
                100.0 * fine.fraction(), 100.0 * last.poses.front().coverage.fraction());
  }
  return 0;
}
