#include "ignav/verification/seed_detection.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include <fmt/format.h>
#include <Eigen/Eigenvalues>

#include "bright_groups.hpp"
#include "seed_split.hpp"

namespace ignav::verification {
namespace {

using Index3 = Eigen::Vector3i;
constexpr std::size_t kMaxRejectedListed = 64;

Status checkSearch(const SeedSearch& s) {
  auto bad = [](const std::string& what) {
    return makeError(ErrorCode::kInvalidArgument, "seed search: " + what);
  };
  auto range = [&](const char* name, double lo, double hi) -> Status {
    if (!(lo >= 0.0 && lo <= hi) || !std::isfinite(hi)) {
      return bad(fmt::format("{} [{:g}, {:g}] must be finite with 0 <= min <= max", name, lo, hi));
    }
    return Ok{};
  };
  if (!std::isfinite(s.min_hu)) return bad("min_hu must be finite");
  if (auto ok = range("metal range (HU·mm³)", s.min_metal_hu_mm3, s.max_metal_hu_mm3); !ok)
    return ok;
  if (auto ok = range("length range (mm)", s.min_length_mm, s.max_length_mm); !ok) return ok;
  if (!(s.max_width_mm > 0.0) || !std::isfinite(s.max_width_mm))
    return bad(fmt::format("max_width_mm = {:g} must be finite and positive", s.max_width_mm));
  if (!(s.min_elongation >= 0.0) || !std::isfinite(s.min_elongation))
    return bad(
        fmt::format("min_elongation = {:g} must be finite and not negative", s.min_elongation));
  if (!(s.max_extent_mm > 0.0) || !std::isfinite(s.max_extent_mm))
    return bad(fmt::format("max_extent_mm = {:g} must be finite and positive", s.max_extent_mm));
  if (!(s.marker_exclusion_mm >= 0.0) || !std::isfinite(s.marker_exclusion_mm)) {
    return bad(fmt::format("marker_exclusion_mm = {:g} must be finite and not negative",
                           s.marker_exclusion_mm));
  }
  for (std::size_t i = 0; i < s.markers_lps_mm.size(); ++i) {
    if (!s.markers_lps_mm[i].allFinite())
      return bad(fmt::format("marker {} has a non-finite coordinate", i + 1));
  }
  if (s.shell_voxels < 0 || s.shell_voxels > 4 || s.background_voxels <= s.shell_voxels ||
      s.background_voxels > 8) {
    return bad(
        fmt::format("shell_voxels = {} and background_voxels = {} must satisfy "
                    "0 <= shell <= 4, shell < background <= 8",
                    s.shell_voxels, s.background_voxels));
  }
  if (s.max_bright_voxels == 0 || s.max_bright_voxels > (std::size_t{1} << 31))
    return bad("max_bright_voxels must be in [1, 2^31]");
  return Ok{};
}

struct GroupView {
  std::uint32_t id = 0;
  std::vector<Index3> voxels;
  std::vector<std::uint32_t> positions;  // each voxel's index into the bright voxels
  Index3 lo, hi;
};

// Centroid, moments, metal and background of one group, over the window around it. Voxels of
// other groups, and voxels nearer to another group than to this one, are left out of both the
// weighting and the background, so that neighbouring seeds do not pull each other.
void refine(const volume::Volume& volume, const SeedSearch& search,
            const std::vector<std::uint32_t>& bright, const std::vector<std::uint32_t>& group_of,
            const GroupView& group, SeedCandidate& c) {
  const auto& g = volume.geometry;
  const Index3 dims(g.dims[0], g.dims[1], g.dims[2]);
  const int ring = search.background_voxels, shell = search.shell_voxels;
  const Index3 wlo = (group.lo.array() - ring).max(0).matrix();
  const Index3 whi = (group.hi.array() + ring).min(dims.array() - 1).matrix();
  const Index3 size = whi - wlo + Index3::Ones();
  auto local = [&](int i, int j, int k) {
    return static_cast<std::size_t>(i - wlo.x()) +
           static_cast<std::size_t>(size.x()) *
               (static_cast<std::size_t>(j - wlo.y()) +
                static_cast<std::size_t>(size.y()) * static_cast<std::size_t>(k - wlo.z()));
  };
  const auto cells = static_cast<std::size_t>(size.prod());
  const std::uint8_t far = static_cast<std::uint8_t>(shell + 1);
  std::vector<std::uint8_t> own(cells, far), other(cells, far);
  auto dilate = [&](std::vector<std::uint8_t>& map, const Index3& v) {
    for (int dz = -shell; dz <= shell; ++dz)
      for (int dy = -shell; dy <= shell; ++dy)
        for (int dx = -shell; dx <= shell; ++dx) {
          const Index3 q = v + Index3(dx, dy, dz);
          if ((q.array() < wlo.array()).any() || (q.array() > whi.array()).any()) continue;
          const auto d =
              static_cast<std::uint8_t>(std::max({std::abs(dx), std::abs(dy), std::abs(dz)}));
          auto& slot = map[local(q.x(), q.y(), q.z())];
          slot = std::min(slot, d);
        }
  };
  for (const auto& v : group.voxels)
    dilate(own, v);
  // Other groups' bright voxels in the window (and in its shell-wide margin, whose own shells
  // reach in): one binary search per row.
  const Index3 olo = (wlo.array() - shell).max(0).matrix();
  const Index3 ohi = (whi.array() + shell).min(dims.array() - 1).matrix();
  for (int k = olo.z(); k <= ohi.z(); ++k) {
    for (int j = olo.y(); j <= ohi.y(); ++j) {
      const auto row = static_cast<std::uint32_t>(volume.index(0, j, k));
      auto it =
          std::lower_bound(bright.begin(), bright.end(), row + static_cast<std::uint32_t>(olo.x()));
      for (; it != bright.end() && *it <= row + static_cast<std::uint32_t>(ohi.x()); ++it) {
        const auto p = static_cast<std::size_t>(it - bright.begin());
        if (group_of[p] == group.id) continue;
        dilate(other, Index3(static_cast<int>(*it - row), j, k));
      }
    }
  }
  std::vector<double> ring_values;
  double peak = -std::numeric_limits<double>::infinity();
  double floor_value = std::numeric_limits<double>::infinity();
  for (int k = wlo.z(); k <= whi.z(); ++k)
    for (int j = wlo.y(); j <= whi.y(); ++j)
      for (int i = wlo.x(); i <= whi.x(); ++i) {
        const std::size_t l = local(i, j, k);
        const double v = volume.valueAt(i, j, k);
        if (own[l] > shell && other[l] > shell) ring_values.push_back(v);
        if (own[l] == 0) peak = std::max(peak, v);
        if (other[l] > 0) floor_value = std::min(floor_value, v);
      }
  double background = floor_value;  // no ring left (a crowded corner): the darkest voxel
  double noise = 0.0;
  if (!ring_values.empty()) {
    background = medianOf(ring_values);
    // The noise: 1.4826 × the median absolute deviation (a normal distribution's SD).
    for (double& v : ring_values)
      v = std::abs(v - background);
    noise = 1.4826 * medianOf(ring_values);
  }
  // Centroid: signed weights (noise averages out instead of biasing). Shape: only weights
  // clear of the noise (3 SD), since noise far from the centre swamps second moments; a shape
  // that loses its faint tails is still the shape. Positions relative to the group's box centre
  // in LPS, for well-conditioned moments.
  const Eigen::Matrix3d to_lps = g.direction * g.spacing_mm.asDiagonal();
  const Eigen::Vector3d centre_ijk = 0.5 * (group.lo + group.hi).cast<double>();
  const double clear = 3.0 * noise;
  double w_sum = 0.0, shape_sum = 0.0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero(), shape_first = Eigen::Vector3d::Zero();
  Eigen::Matrix3d shape_second = Eigen::Matrix3d::Zero();
  for (int k = wlo.z(); k <= whi.z(); ++k)
    for (int j = wlo.y(); j <= whi.y(); ++j)
      for (int i = wlo.x(); i <= whi.x(); ++i) {
        const std::size_t l = local(i, j, k);
        if (own[l] > shell || own[l] >= other[l]) continue;
        const double w = volume.valueAt(i, j, k) - background;
        const Eigen::Vector3d x = to_lps * (Eigen::Vector3d(i, j, k) - centre_ijk);
        w_sum += w;
        first += w * x;
        if (w > clear) {
          shape_sum += w;
          shape_first += w * x;
          shape_second += w * x * x.transpose();
        }
      }
  c.noise_hu = noise;
  c.background_hu = background;
  c.peak_hu = peak;
  const double voxel_mm3 = g.spacing_mm.prod();
  c.metal_hu_mm3 = w_sum * voxel_mm3;
  if (!(w_sum > 0.0) || !(shape_sum > 0.0)) {
    c.reason = "no_contrast";
    c.rejected = fmt::format("no metal above the background ({:.0f} HU) around it", background);
    return;
  }
  const Eigen::Vector3d mean = first / w_sum;
  c.centroid_lps_mm = g.toLps(centre_ijk) + mean;
  // A voxel's own extent adds s²/12 per grid axis to what the moments see.
  const Eigen::Vector3d voxel_var = g.spacing_mm.cwiseAbs2() / 12.0;
  const Eigen::Vector3d shape_mean = shape_first / shape_sum;
  const Eigen::Matrix3d covariance = shape_second / shape_sum -
                                     shape_mean * shape_mean.transpose() -
                                     g.direction * voxel_var.asDiagonal() * g.direction.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
  eigen.computeDirect(covariance);
  const Eigen::Vector3d lambda = eigen.eigenvalues();  // ascending
  Eigen::Vector3d axis = eigen.eigenvectors().col(2).normalized();
  Eigen::Index largest = 0;
  axis.cwiseAbs().maxCoeff(&largest);
  if (axis[largest] < 0.0) axis = -axis;
  c.axis_lps = axis;
  c.length_mm = std::sqrt(12.0 * std::max(lambda[2], 0.0));
  c.width_mm = 4.0 * std::sqrt(std::max(lambda[1], 0.0));
  c.elongation = lambda[1] > 0.0 ? lambda[2] / lambda[1] : std::numeric_limits<double>::infinity();
}

void judge(const SeedSearch& s, SeedCandidate& c) {
  if (!c.reason.empty()) return;
  auto reject = [&](const char* reason, std::string sentence) {
    c.reason = reason;
    c.rejected = std::move(sentence);
  };
  if (c.metal_hu_mm3 < s.min_metal_hu_mm3) {
    reject("too_little_metal",
           fmt::format("too little metal for a seed: {:.0f} HU·mm³ < {:g} (a calcification, "
                       "bone or noise)",
                       c.metal_hu_mm3, s.min_metal_hu_mm3));
  } else if (c.metal_hu_mm3 > s.max_metal_hu_mm3) {
    reject("too_much_metal",
           fmt::format("too much metal for one seed: {:.0f} HU·mm³ > {:g} (seeds touching, a "
                       "marker or a wire)",
                       c.metal_hu_mm3, s.max_metal_hu_mm3));
  } else if (c.width_mm > s.max_width_mm) {
    reject("too_wide", fmt::format("too wide for a seed: {:.2f} mm > {:g} mm (a bead or bone)",
                                   c.width_mm, s.max_width_mm));
  } else if (c.length_mm < s.min_length_mm) {
    reject("too_short",
           fmt::format("too short for a seed: {:.2f} mm < {:g} mm", c.length_mm, s.min_length_mm));
  } else if (c.elongation < s.min_elongation) {
    reject("not_elongated",
           fmt::format("round, not a rod: {:.2f} mm long and {:.2f} mm wide (a bead, a "
                       "calcification)",
                       c.length_mm, c.width_mm));
  } else if (c.length_mm > s.max_length_mm) {
    reject("too_long",
           fmt::format("too long for a seed: {:.2f} mm > {:g} mm (seeds end to end, a wire)",
                       c.length_mm, s.max_length_mm));
  }
}

// What a group of touching seeds is rejected for: more metal, length, width or roundness than
// one seed has.
bool mayBeTouchingSeeds(const std::string& reason) {
  return reason == "too_much_metal" || reason == "too_long" || reason == "too_wide" ||
         reason == "not_elongated";
}

// The group `merged` (refined and rejected as one) cut at its intensity valleys into seeds, each
// refined with the others as its neighbours; none unless every part is a seed. `labels` is the
// bright voxels' grouping, which the parts are written into as new groups from `next_id` on.
std::vector<SeedCandidate> separateTouching(const volume::Volume& volume, const SeedSearch& search,
                                            const std::vector<std::uint32_t>& bright,
                                            std::vector<std::uint32_t>& labels,
                                            std::uint32_t& next_id, const GroupView& merged,
                                            const SeedCandidate& as_one) {
  std::vector<double> values;
  values.reserve(merged.voxels.size());
  for (const auto& v : merged.voxels)
    values.push_back(volume.valueAt(v.x(), v.y(), v.z()));
  // A core stands for a seed when it rises clear of the noise and of the aliasing along one seed.
  const double depth = std::max(3.0 * as_one.noise_hu, 0.1 * (as_one.peak_hu - search.min_hu));
  const auto split = splitAtValleys(merged.voxels, values, search.min_hu, depth);
  if (!split) return {};
  std::vector<GroupView> parts(split->parts);
  for (std::size_t p = 0; p < parts.size(); ++p)
    parts[p].id = next_id + static_cast<std::uint32_t>(p);
  for (std::size_t e = 0; e < merged.voxels.size(); ++e) {
    GroupView& part = parts[split->part_of[e]];
    part.voxels.push_back(merged.voxels[e]);
    part.positions.push_back(merged.positions[e]);
    labels[merged.positions[e]] = part.id;
  }
  next_id += static_cast<std::uint32_t>(parts.size());
  std::vector<SeedCandidate> out;
  for (auto& part : parts) {
    part.lo = part.hi = part.voxels.front();
    for (const auto& v : part.voxels) {
      part.lo = part.lo.cwiseMin(v);
      part.hi = part.hi.cwiseMax(v);
    }
    SeedCandidate c;
    c.voxel_count = part.voxels.size();
    c.extent_mm = (part.hi - part.lo + Index3::Ones())
                      .cast<double>()
                      .cwiseProduct(volume.geometry.spacing_mm)
                      .maxCoeff();
    refine(volume, search, bright, labels, part, c);
    judge(search, c);
    if (!c.reason.empty()) return {};
    c.touching = parts.size();
    c.valley_hu = split->level_hu;
    out.push_back(std::move(c));
  }
  return out;
}

}  // namespace

Expected<SeedDetection> findSeeds(const volume::Volume& volume, const SeedSearch& search) {
  if (auto ok = checkSearch(search); !ok) return ok.error();
  const auto& g = volume.geometry;
  auto found = findBrightGroups(volume, search.min_hu, search.max_bright_voxels, "seed search",
                                "the seeds' intensity");
  if (!found) return found.error();
  const BrightGroups& groups = *found;
  const auto& start = groups.start;
  const std::size_t group_count = groups.count();
  SeedDetection result;
  result.bright_voxels = groups.bright.size();
  result.groups = group_count;
  std::size_t markers = 0, separated = 0;
  std::vector<std::uint32_t> labels;  // the grouping with split groups' parts, made when needed
  auto next_id = static_cast<std::uint32_t>(group_count);
  for (std::size_t q = 0; q < group_count; ++q) {
    GroupView group;
    group.id = static_cast<std::uint32_t>(q);
    group.voxels.reserve(start[q + 1] - start[q]);
    SeedCandidate c;
    c.peak_hu = -std::numeric_limits<double>::infinity();
    Eigen::Vector3d mean_ijk = Eigen::Vector3d::Zero();
    for (std::size_t e = start[q]; e < start[q + 1]; ++e) {
      const Index3 v = groups.voxel(e);
      group.voxels.push_back(v);
      group.positions.push_back(groups.members[e]);
      mean_ijk += v.cast<double>();
      c.peak_hu = std::max(c.peak_hu, volume.valueAt(v.x(), v.y(), v.z()));
    }
    group.lo = group.hi = group.voxels.front();
    for (const auto& v : group.voxels) {
      group.lo = group.lo.cwiseMin(v);
      group.hi = group.hi.cwiseMax(v);
    }
    c.voxel_count = group.voxels.size();
    c.extent_mm =
        (group.hi - group.lo + Index3::Ones()).cast<double>().cwiseProduct(g.spacing_mm).maxCoeff();
    c.centroid_lps_mm = g.toLps(mean_ijk / static_cast<double>(group.voxels.size()));
    if (c.extent_mm > search.max_extent_mm) {
      c.reason = "too_long";
      c.rejected = fmt::format(
          "a bright structure {:.1f} mm long, > {:g} mm (bone, the cannula "
          "or the stylet)",
          c.extent_mm, search.max_extent_mm);
    }
    for (std::size_t m = 0; c.reason.empty() && m < search.markers_lps_mm.size(); ++m) {
      const double d = (c.centroid_lps_mm - search.markers_lps_mm[m]).norm();
      if (d <= search.marker_exclusion_mm) {
        c.reason = "marker";
        c.rejected = fmt::format("robot marker {} ({:.2f} mm from its position)", m + 1, d);
        ++markers;
      }
    }
    const bool refined = c.reason.empty();
    if (refined) refine(volume, search, groups.bright, groups.group_of, group, c);
    judge(search, c);
    if (refined && mayBeTouchingSeeds(c.reason)) {
      if (labels.empty()) labels = groups.group_of;
      auto seeds = separateTouching(volume, search, groups.bright, labels, next_id, group, c);
      if (!seeds.empty()) {
        separated += seeds.size();
        for (auto& seed : seeds)
          result.seeds.push_back(std::move(seed));
        continue;
      }
      c.rejected += "; no intensity valley parts it into seeds";
    }
    if (c.reason.empty()) {
      result.seeds.push_back(std::move(c));
    } else if (result.rejected.size() < kMaxRejectedListed) {
      result.rejected.push_back(std::move(c));
    } else {
      ++result.rejected_not_listed;
    }
  }
  const std::size_t rejected = result.rejected.size() + result.rejected_not_listed;
  result.summary = fmt::format(
      "{} seed{} found{}: {} voxels at or above {:g} HU in {} groups, {} rejected{}",
      result.seeds.size(), result.seeds.size() == 1 ? "" : "s",
      separated > 0 ? fmt::format(" ({} separated where their images touched)", separated)
                    : std::string(),
      result.bright_voxels, search.min_hu, group_count, rejected,
      markers > 0 ? fmt::format(" ({} robot marker{})", markers, markers == 1 ? "" : "s")
                  : std::string());
  // Why each group that is not a marker was rejected, where it is (the first few).
  constexpr std::size_t kRejectionsSaid = 4;
  std::size_t said = 0;
  for (const auto& r : result.rejected) {
    if (r.reason == "marker") continue;
    if (said++ == kRejectionsSaid) {
      result.summary += "; …";
      break;
    }
    result.summary +=
        fmt::format("; rejected at LPS ({:.1f}, {:.1f}, {:.1f}): {}", r.centroid_lps_mm.x(),
                    r.centroid_lps_mm.y(), r.centroid_lps_mm.z(), r.rejected);
  }
  if (result.seeds.empty()) {
    result.summary += "; lower min_hu or min_metal_hu_mm3 if seeds are in the scan";
  }
  return result;
}

}  // namespace ignav::verification
