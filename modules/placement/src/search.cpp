// The search for the robot's pose (robot_placement.hpp): a coarse sweep by reach alone, then
// pattern searches on the full coverage; and the brute-force grid it is checked against.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include "ignav/placement/robot_placement.hpp"

namespace ignav::placement {
namespace {

constexpr double kDeg = M_PI / 180.0;
// The coarse sweep's steps: directions about this far apart, axes on this grid.
constexpr double kSweepTilt_deg = 5.0;
constexpr double kSweepShift_mm = 2.0;
constexpr std::size_t kSweepSamples = 800;
// Poses this far apart (either) count as distinct alternatives.
constexpr double kDistinct_mm = 5.0;
constexpr double kDistinct_deg = 5.0;
// The pattern search: first steps, halved this many times, and at most this many evaluations
// from one start.
constexpr double kFirstTiltStep_deg = 2.0;
constexpr double kFirstStep_mm = 2.0;
constexpr int kHalvings = 3;
constexpr std::size_t kMaxEvaluationsPerStart = 160;

// A pose in the search's coordinates: the axis' direction as (α, β) = tan(tilt) along the two
// axes across the site's direction, where it crosses the plane through the target's centroid
// across that direction (u, v), and how far the robot's origin stands before that plane (depth).
struct PoseParameters {
  double alpha = 0.0, beta = 0.0, u_mm = 0.0, v_mm = 0.0, depth_mm = 0.0;
};

struct Frame {
  Eigen::Vector3d centroid, n, b1, b2;
  double max_tilt_rad = 0.0;
  double max_shift_mm = 0.0;
};

Frame frameOf(const CoverageModel& model, const PlacementLimits& limits) {
  Frame f;
  f.centroid = model.targetCentroid();
  f.n = limits.insertion_lps.normalized();
  const auto basis = RobotPose::along(Eigen::Vector3d::Zero(), f.n).rotation;
  f.b1 = basis.col(0);
  f.b2 = basis.col(1);
  f.max_tilt_rad = limits.max_tilt_deg * kDeg;
  f.max_shift_mm = limits.max_shift_mm;
  return f;
}

Eigen::Vector3d axisOf(const Frame& f, const PoseParameters& x) {
  return (f.n + x.alpha * f.b1 + x.beta * f.b2).normalized();
}
Eigen::Vector3d linePointOf(const Frame& f, const PoseParameters& x) {
  return f.centroid + x.u_mm * f.b1 + x.v_mm * f.b2;
}
RobotPose poseOf(const Frame& f, const PoseParameters& x) {
  const Eigen::Vector3d a = axisOf(f, x);
  return RobotPose::along(linePointOf(f, x) - x.depth_mm * a, a);
}
double tiltOf(const PoseParameters& x) {
  return std::atan(std::hypot(x.alpha, x.beta));
}
// From the centroid to the axis.
double shiftOf(const Frame& f, const Eigen::Vector3d& a, const Eigen::Vector3d& line_point) {
  const Eigen::Vector3d d = f.centroid - line_point;
  return (d - d.dot(a) * a).norm();
}

// The least depth that keeps the robot's origin outside the skin by the site's distance, for an
// axis through `line_point` (depth measured before the centroid's plane across the site's
// direction, along the axis).
double leastDepth(const CoverageModel& model, const PlacementLimits& limits,
                  const Eigen::Vector3d& a, const Eigen::Vector3d& line_point) {
  if (!model.inputs().ct) return -std::numeric_limits<double>::infinity();
  const auto skin = model.skinEntry(RobotPose::along(line_point, a), limits.skin_hu);
  // skin_distance is from line_point (depth 0) to the entry: negative when the entry lies before.
  return limits.min_skin_distance_mm - skin.skin_distance_mm;
}

bool admissible(const Frame& f, const PoseParameters& x) {
  if (tiltOf(x) > f.max_tilt_rad + 1e-12) return false;
  return shiftOf(f, axisOf(f, x), linePointOf(f, x)) <= f.max_shift_mm + 1e-9;
}

// The best depth by reach alone for one axis, by sweeping the depths at which each sample is
// within reach (an interval as long as the cannula's travel); `reached` 0 when none is.
struct SweptAxis {
  PoseParameters x;
  std::size_t reached = 0;
};
SweptAxis sweepDepth(const CoverageModel& model, const Frame& f, PoseParameters x,
                     double least_depth, std::vector<double>& starts, std::vector<double>& ends) {
  const Eigen::Vector3d a = axisOf(f, x);
  const RobotPose at_line = RobotPose::along(linePointOf(f, x), a);  // depth 0
  const double travel = model.inputs().kinematics->instrument().cannula_travel_mm;
  starts.clear();
  ends.clear();
  // Reach alone only ranks the axes: a few hundred samples of the target do that as well as all.
  const auto& samples = model.samplePoints();
  const std::size_t stride = std::max<std::size_t>(1, samples.size() / kSweepSamples);
  for (std::size_t n = 0; n < samples.size(); n += stride) {
    const Eigen::Vector3d q = at_line.toRobot(samples[n]);
    const double z0 = model.depthAtHome_mm(std::hypot(q.x(), q.y()));
    if (std::isnan(z0)) continue;
    // At depth d the point's robot z is q.z - d, and z_c = z0 - (q.z - d) must lie in [0, travel].
    starts.push_back(q.z() - z0);
    ends.push_back(q.z() - z0 + travel);
  }
  SweptAxis best{x, 0};
  if (starts.empty()) return best;
  std::sort(starts.begin(), starts.end());
  std::sort(ends.begin(), ends.end());
  auto count = [&](double d) {
    const auto began = std::upper_bound(starts.begin(), starts.end(), d) - starts.begin();
    const auto over = std::lower_bound(ends.begin(), ends.end(), d) - ends.begin();
    return static_cast<std::size_t>(began - over);
  };
  double best_d = least_depth;
  std::size_t best_n = std::isfinite(least_depth) ? count(least_depth) : 0;
  for (const double s : starts) {
    if (s < least_depth) continue;
    const auto n = count(s);
    if (n > best_n) {
      best_n = n;
      best_d = s;
    }
  }
  if (best_n == 0) return best;
  // The middle of the best plateau: it ends where the next sample leaves or the next one joins.
  const auto next_start = std::upper_bound(starts.begin(), starts.end(), best_d);
  const auto next_end = std::lower_bound(ends.begin(), ends.end(), best_d);
  double plateau_end = std::numeric_limits<double>::infinity();
  if (next_start != starts.end()) plateau_end = *next_start;
  if (next_end != ends.end()) plateau_end = std::min(plateau_end, *next_end);
  if (std::isfinite(plateau_end)) best_d = 0.5 * (best_d + plateau_end);
  best.x.depth_mm = best_d;
  best.reached = best_n;
  return best;
}

bool distinct(const Frame& f, const PoseParameters& x, const PoseParameters& y) {
  const Eigen::Vector3d ax = axisOf(f, x), ay = axisOf(f, y);
  const double angle = std::acos(std::clamp(ax.dot(ay), -1.0, 1.0)) / kDeg;
  const double apart = (linePointOf(f, x) - linePointOf(f, y)).norm();
  return angle > kDistinct_deg || apart > kDistinct_mm;
}

PlacedPose describe(const CoverageModel& model, const PlacementLimits& limits, const Frame& f,
                    const RobotPose& pose, Coverage coverage) {
  PlacedPose placed;
  placed.pose = pose;
  placed.coverage = std::move(coverage);
  placed.skin = model.skinEntry(pose, limits.skin_hu);
  const double cosine = std::clamp(pose.insertion().dot(f.n), -1.0, 1.0);
  placed.tilt_deg = std::acos(cosine) / kDeg;
  placed.shift_mm = shiftOf(f, pose.insertion(), pose.origin_lps_mm);
  return placed;
}

// Tilt levels 0, step, ... up to the limit (steps of at most `step_deg`), each with azimuths
// about as far apart along its circle.
std::vector<PoseParameters> directions(const Frame& f, double step_deg) {
  std::vector<PoseParameters> out{{}};
  if (f.max_tilt_rad <= 0.0) return out;
  const int levels = static_cast<int>(std::ceil(f.max_tilt_rad / (step_deg * kDeg) - 1e-9));
  const double step = f.max_tilt_rad / levels;
  for (int k = 1; k <= levels; ++k) {
    const double tilt = k * step;
    const int around = std::max(3, static_cast<int>(std::ceil(2.0 * M_PI * tilt / step - 1e-9)));
    for (int m = 0; m < around; ++m) {
      const double phi = 2.0 * M_PI * m / around;
      out.push_back({std::tan(tilt) * std::cos(phi), std::tan(tilt) * std::sin(phi), 0, 0, 0});
    }
  }
  return out;
}

// Axis offsets on a square grid within the shift limit.
std::vector<std::pair<double, double>> offsets(double max_shift_mm, double step_mm) {
  std::vector<std::pair<double, double>> out;
  const int n = static_cast<int>(std::floor(max_shift_mm / step_mm + 1e-9));
  for (int i = -n; i <= n; ++i)
    for (int j = -n; j <= n; ++j)
      if (std::hypot(i * step_mm, j * step_mm) <= max_shift_mm + 1e-9)
        out.emplace_back(i * step_mm, j * step_mm);
  return out;
}

}  // namespace

Expected<Placement> placeRobot(const CoverageModel& search_model, const CoverageModel& final_model,
                               const PlacementLimits& limits, std::size_t alternatives,
                               const Progress& progress) {
  if (auto valid = limits.validate(); !valid.ok()) return valid.error();
  const Frame f = frameOf(search_model, limits);
  const auto dirs = directions(f, kSweepTilt_deg);
  const auto laterals = offsets(f.max_shift_mm, kSweepShift_mm);
  const std::size_t starts_wanted = alternatives + 3;
  const std::size_t total = dirs.size() + starts_wanted * kMaxEvaluationsPerStart / 4;
  auto report = [&](std::size_t done) {
    if (progress) progress(std::min(done, total - 1), total);
  };

  // 1. Every axis of the coarse grid at its best depth, by reach alone.
  std::vector<SweptAxis> swept;
  std::vector<double> starts, ends;
  for (std::size_t d = 0; d < dirs.size(); ++d) {
    report(d);
    for (const auto& [u, v] : laterals) {
      PoseParameters x = dirs[d];
      x.u_mm = u;
      x.v_mm = v;
      if (!admissible(f, x)) continue;
      const double least = leastDepth(search_model, limits, axisOf(f, x), linePointOf(f, x));
      auto s = sweepDepth(search_model, f, x, least, starts, ends);
      if (s.reached > 0) swept.push_back(s);
    }
  }
  if (swept.empty()) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("no pose within the site's limits (tilt ≤ {:g}°, shift ≤ {:g} mm, "
                    "origin ≥ {:g} mm outside the skin) reaches any of the target",
                    limits.max_tilt_deg, limits.max_shift_mm, limits.min_skin_distance_mm),
        "no_placement");
  }
  std::stable_sort(swept.begin(), swept.end(),
                   [](const SweptAxis& a, const SweptAxis& b) { return a.reached > b.reached; });
  std::vector<PoseParameters> seeds;
  for (const auto& s : swept) {
    if (seeds.size() == starts_wanted) break;
    if (std::all_of(seeds.begin(), seeds.end(),
                    [&](const PoseParameters& y) { return distinct(f, s.x, y); }))
      seeds.push_back(s.x);
  }

  // 2. From each, a pattern search on the full coverage.
  Placement placement;
  struct Found {
    PoseParameters x;
    Coverage coverage;
  };
  std::vector<Found> found;
  std::size_t done = dirs.size();
  for (const auto& seed : seeds) {
    PoseParameters x = seed;
    Coverage best = search_model.coverage(poseOf(f, x));
    std::size_t used = 1;
    double tilt_step = std::tan(kFirstTiltStep_deg * kDeg), step = kFirstStep_mm;
    for (int level = 0; level <= kHalvings && used < kMaxEvaluationsPerStart; ++level) {
      bool improved = true;
      while (improved && used < kMaxEvaluationsPerStart) {
        improved = false;
        for (int move = 0; move < 10 && used < kMaxEvaluationsPerStart; ++move) {
          PoseParameters y = x;
          const double sign = move % 2 ? -1.0 : 1.0;
          switch (move / 2) {
            case 0:
              y.alpha += sign * tilt_step;
              break;
            case 1:
              y.beta += sign * tilt_step;
              break;
            case 2:
              y.u_mm += sign * step;
              break;
            case 3:
              y.v_mm += sign * step;
              break;
            default:
              y.depth_mm += sign * step;
              break;
          }
          if (!admissible(f, y)) continue;
          if (y.depth_mm < leastDepth(search_model, limits, axisOf(f, y), linePointOf(f, y)))
            continue;
          const Coverage c = search_model.coverage(poseOf(f, y));
          ++used;
          if (used % 4 == 0) report(++done);
          if (c.covered > best.covered) {
            best = c;
            x = y;
            improved = true;
          }
        }
      }
      tilt_step *= 0.5;
      step *= 0.5;
    }
    placement.evaluations += used;
    found.push_back({x, best});
  }

  // 3. The best first, then those distinct from every better one, judged on the finer lattice.
  // A start whose reach looked promising may keep no clearance anywhere: a pose that covers
  // nothing is no alternative.
  std::stable_sort(found.begin(), found.end(), [](const Found& a, const Found& b) {
    return a.coverage.covered > b.coverage.covered;
  });
  std::vector<PoseParameters> kept;
  for (const auto& candidate : found) {
    if (kept.size() == alternatives + 1) break;
    if (candidate.coverage.covered == 0 && !kept.empty()) break;
    if (std::all_of(kept.begin(), kept.end(),
                    [&](const PoseParameters& y) { return distinct(f, candidate.x, y); }))
      kept.push_back(candidate.x);
  }
  for (const auto& x : kept) {
    const RobotPose pose = poseOf(f, x);
    placement.poses.push_back(describe(final_model, limits, f, pose, final_model.coverage(pose)));
    ++placement.evaluations;
  }
  std::stable_sort(placement.poses.begin(), placement.poses.end(),
                   [](const PlacedPose& a, const PlacedPose& b) {
                     return a.coverage.covered > b.coverage.covered;
                   });
  if (placement.poses.front().coverage.covered == 0) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("no pose within the site's limits (tilt ≤ {:g}°, shift ≤ {:g} mm) "
                                 "covers any of the target with every clearance kept",
                                 limits.max_tilt_deg, limits.max_shift_mm),
                     "no_placement");
  }
  // The finer lattice may find nothing where the coarser found a little.
  while (placement.poses.back().coverage.covered == 0)
    placement.poses.pop_back();
  placement.samples = final_model.samples();
  if (progress) progress(total, total);
  return placement;
}

PlacedPose bruteForcePlacement(const CoverageModel& model, const PlacementLimits& limits,
                               const PoseGrid& grid, std::size_t* poses_tried) {
  const Frame f = frameOf(model, limits);
  const auto& kin = *model.inputs().kinematics;
  // Depths at which the feasible volume can meet the target at all: its robot z-range against
  // the samples' extent along each axis.
  double z_hi = -std::numeric_limits<double>::infinity(), z_lo = -z_hi;
  for (int n = 0; n <= 64; ++n) {
    const double z0 = kin.tipDepthAtHome_mm(kin.instrument().stylet_travel_mm * n / 64.0);
    z_hi = std::max(z_hi, z0);
    z_lo = std::min(z_lo, z0 - kin.instrument().cannula_travel_mm);
  }
  std::vector<PoseParameters> poses;
  for (const auto& dir : directions(f, grid.tilt_step_deg)) {
    for (const auto& [u, v] : offsets(f.max_shift_mm, grid.shift_step_mm)) {
      PoseParameters x = dir;
      x.u_mm = u;
      x.v_mm = v;
      if (!admissible(f, x)) continue;
      const Eigen::Vector3d a = axisOf(f, x), line_point = linePointOf(f, x);
      const double least = leastDepth(model, limits, a, line_point);
      double s_lo = std::numeric_limits<double>::infinity(), s_hi = -s_lo;
      for (const auto& p : model.samplePoints()) {
        s_lo = std::min(s_lo, (p - line_point).dot(a));
        s_hi = std::max(s_hi, (p - line_point).dot(a));
      }
      // A sample s along the axis is within reach at depths [-s - z0, -s - z0 + travel].
      for (double d = -z_hi - s_hi; d <= -z_lo - s_lo + 1e-9; d += grid.depth_step_mm) {
        if (d < least) continue;
        x.depth_mm = d;
        poses.push_back(x);
      }
    }
  }
  if (poses_tried) *poses_tried = poses.size();
  const unsigned threads = std::max(1u, grid.threads);
  std::vector<std::pair<std::size_t, std::size_t>> best(threads, {0, poses.size()});
  auto work = [&](unsigned t) {
    for (std::size_t n = t; n < poses.size(); n += threads) {
      const auto covered = model.coverage(poseOf(f, poses[n])).covered;
      if (best[t].second == poses.size() || covered > best[t].first) best[t] = {covered, n};
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t)
    pool.emplace_back(work, t);
  work(0);
  for (auto& th : pool)
    th.join();
  std::pair<std::size_t, std::size_t> winner{0, poses.size()};
  for (const auto& b : best)
    if (b.second != poses.size() && (winner.second == poses.size() || b.first > winner.first ||
                                     (b.first == winner.first && b.second < winner.second)))
      winner = b;
  if (winner.second == poses.size()) return PlacedPose{};
  const RobotPose pose = poseOf(f, poses[winner.second]);
  return describe(model, limits, f, pose, model.coverage(pose));
}

}  // namespace ignav::placement
