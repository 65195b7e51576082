#include "ignav/verification/needle_detection.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <Eigen/Dense>

#include "bright_groups.hpp"

namespace ignav::verification {
namespace {

// How far before the thresholded end the tip's reference point lies (mm): the edge's blur (half
// a 1.25 mm slice and three 0.4 mm PSF sigmas, ~1.8 mm) must fall wholly past it.
constexpr double kReferenceBack_mm = 3.0;
// The centreline's stretch fitted across the axis at the tip (mm before the reference point).
constexpr double kLateralFit_mm = 6.0;
// How far past the thresholded end the metal is summed (mm).
constexpr double kTailReach_mm = 3.0;

Status checkSearch(const NeedleSearch& s) {
  auto bad = [](const std::string& what) {
    return makeError(ErrorCode::kInvalidArgument, "needle search: " + what);
  };
  if (!s.insertion_lps.allFinite() || !(s.insertion_lps.norm() > 1e-9))
    return bad("insertion_lps must be a finite, non-zero direction");
  if (!std::isfinite(s.min_hu)) return bad("min_hu must be finite");
  for (auto [name, v] : {std::pair{"min_length_mm", s.min_length_mm},
                         std::pair{"max_diameter_mm", s.max_diameter_mm},
                         std::pair{"tube_radius_mm", s.tube_radius_mm},
                         std::pair{"step_mm", s.step_mm}, std::pair{"plateau_mm", s.plateau_mm},
                         std::pair{"max_entry_angle_deg", s.max_entry_angle_deg}}) {
    if (!(v > 0.0) || !std::isfinite(v))
      return bad(fmt::format("{} = {:g} must be finite and positive", name, v));
  }
  if (!(s.marker_exclusion_mm >= 0.0) || !std::isfinite(s.marker_exclusion_mm))
    return bad("marker_exclusion_mm must be finite and not negative");
  if (s.max_bright_voxels == 0) return bad("max_bright_voxels must be at least 1");
  return Ok{};
}

struct BrightVoxel {
  Eigen::Vector3d lps_mm;
  double hu;
};

// The centreline from the end the needle comes in by: slab centroids, step_mm apart.
// `slab_mm`: how thick a slab must be to hold a voxel centre wherever it is (the largest
// spacing).
std::vector<Eigen::Vector3d> trackCentreline(const std::vector<BrightVoxel>& voxels,
                                             const Eigen::Vector3d& insertion,
                                             const NeedleSearch& search, double reach_mm,
                                             double slab_mm) {
  double s_min = std::numeric_limits<double>::infinity();
  for (const auto& v : voxels)
    s_min = std::min(s_min, v.lps_mm.dot(insertion));
  auto centroid = [&](const Eigen::Vector3d& at, const Eigen::Vector3d& dir, double half_mm,
                      double radius_mm, Eigen::Vector3d& out) {
    double w = 0.0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& v : voxels) {
      const Eigen::Vector3d d = v.lps_mm - at;
      const double along = d.dot(dir);
      if (std::abs(along) > half_mm || (d - along * dir).norm() > radius_mm) continue;
      w += v.hu;
      sum += v.hu * v.lps_mm;
    }
    if (!(w > 0.0)) return false;
    out = sum / w;
    return true;
  };
  // Steps no thinner than a slice: a slab must hold voxel centres wherever it falls.
  const double step = std::max(search.step_mm, slab_mm);
  std::vector<Eigen::Vector3d> line;
  Eigen::Vector3d start;
  // The entry end: everything within a step of the shallowest voxel.
  {
    double w = 0.0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& v : voxels) {
      if (v.lps_mm.dot(insertion) > s_min + step) continue;
      w += v.hu;
      sum += v.hu * v.lps_mm;
    }
    start = sum / w;
  }
  line.push_back(start);
  Eigen::Vector3d dir = insertion;
  const auto max_steps = static_cast<std::size_t>(reach_mm / step) + 8;
  const double radius = search.tube_radius_mm + step;
  while (line.size() < max_steps) {
    Eigen::Vector3d next;
    if (!centroid(line.back() + step * dir, dir, 0.5 * step, radius, next)) break;
    if ((next - line.back()).dot(dir) < 0.25 * step) break;  // no longer advancing
    line.push_back(next);
    // The direction over the last three steps: a centroid's jitter is smoothed, a bend is not.
    const Eigen::Vector3d chord = line.back() - line[line.size() > 3 ? line.size() - 4 : 0];
    if (chord.norm() > 1e-9) dir = chord.normalized();
  }
  return line;
}

// Within [lo, hi] of a voxel's projection onto an axis, taken as uniform over t ± half.
double shareWithin(double t, double half, double lo, double hi) {
  if (half <= 0.0) return t >= lo && t < hi ? 1.0 : 0.0;
  const double a = std::max(lo, t - half), b = std::min(hi, t + half);
  return b > a ? (b - a) / (2.0 * half) : 0.0;
}

// Each tracked point moved to the metal's centroid around it: every voxel within the tube and
// within window_mm along the direction (soft ends), weighed by its HU above the local background
// (the ring's median: the needle crosses air, gel and bone). The slab centroids of the tracking
// see only the bright voxels and alias with the slices by up to half a millimetre.
std::vector<Eigen::Vector3d> refineCentreline(const volume::Volume& volume,
                                              const std::vector<Eigen::Vector3d>& line,
                                              double tube_radius_mm) {
  constexpr double kWindow_mm = 3.0;
  const auto& g = volume.geometry;
  const Eigen::Matrix3d edges = g.direction * g.spacing_mm.asDiagonal();
  const double ring_out = tube_radius_mm + 1.5;
  std::vector<Eigen::Vector3d> out;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const Eigen::Vector3d chord = line[std::min(i + 1, line.size() - 1)] - line[i > 0 ? i - 1 : 0];
    if (!(chord.norm() > 1e-9)) {
      out.push_back(line[i]);
      continue;
    }
    const Eigen::Vector3d dir = chord.normalized(), at = line[i];
    const double half = 0.5 * (edges.transpose() * dir).cwiseAbs().sum();
    const double reach = 0.5 * kWindow_mm + ring_out;
    const Eigen::Vector3d lo = g.toIjk(at).array() - reach / g.spacing_mm.minCoeff();
    const Eigen::Vector3d hi = g.toIjk(at).array() + reach / g.spacing_mm.minCoeff();
    struct Sample {
      Eigen::Vector3d lps;
      double hu, share;
    };
    std::vector<Sample> tube;
    std::vector<double> ring;
    for (int k = std::max(0, static_cast<int>(std::floor(lo.z())));
         k <= std::min(g.dims[2] - 1, static_cast<int>(std::ceil(hi.z()))); ++k)
      for (int j = std::max(0, static_cast<int>(std::floor(lo.y())));
           j <= std::min(g.dims[1] - 1, static_cast<int>(std::ceil(hi.y()))); ++j)
        for (int x = std::max(0, static_cast<int>(std::floor(lo.x())));
             x <= std::min(g.dims[0] - 1, static_cast<int>(std::ceil(hi.x()))); ++x) {
          const Eigen::Vector3d lps = g.toLps(Eigen::Vector3d(x, j, k));
          const Eigen::Vector3d d = lps - at;
          const double t = d.dot(dir), r = (d - t * dir).norm();
          const double share = shareWithin(t, half, -0.5 * kWindow_mm, 0.5 * kWindow_mm);
          if (share <= 0.0) continue;
          if (r <= tube_radius_mm) {
            tube.push_back({lps, volume.valueAt(x, j, k), share});
          } else if (r <= ring_out) {
            ring.push_back(volume.valueAt(x, j, k));
          }
        }
    if (tube.empty() || ring.empty()) {
      out.push_back(line[i]);
      continue;
    }
    const double background = medianOf(ring);
    double w_sum = 0.0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const auto& s : tube) {
      const double w = s.share * (s.hu - background);
      w_sum += w;
      sum += w * (s.lps - at);
    }
    // Only across the direction: along it the window's centre is where the point is.
    const Eigen::Vector3d shift =
        w_sum > 0.0 ? Eigen::Vector3d(sum / w_sum) : Eigen::Vector3d::Zero();
    out.push_back(at + shift - shift.dot(dir) * dir);
  }
  return out;
}

struct TipFit {
  bool ok = false;
  Eigen::Vector3d tip, direction;
  double metal_per_mm = 0.0, diameter_mm = 0.0, background_hu = 0.0, reference_t = 0.0;
};

// The tip along `axis` from `origin` (a point on the wire near its end): the metal past a
// reference point over the metal per mm before it. `end_t`: the thresholded end along axis.
TipFit fitTip(const volume::Volume& volume, const NeedleSearch& search,
              const Eigen::Vector3d& origin, const Eigen::Vector3d& axis, double end_t) {
  const auto& g = volume.geometry;
  const double t_ref = end_t - kReferenceBack_mm;
  const double t_lo = t_ref - std::max(search.plateau_mm, kLateralFit_mm) - 1.0;
  const double t_hi = end_t + kTailReach_mm;
  const double ring_in = search.tube_radius_mm, ring_out = search.tube_radius_mm + 1.5;
  // The window's box in IJK.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (double t : {t_lo, t_hi}) {
    const Eigen::Vector3d c = origin + t * axis;
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3d off((corner & 1) ? ring_out : -ring_out,
                                (corner & 2) ? ring_out : -ring_out,
                                (corner & 4) ? ring_out : -ring_out);
      const Eigen::Vector3d ijk = g.toIjk(c + off);
      lo = lo.cwiseMin(ijk);
      hi = hi.cwiseMax(ijk);
    }
  }
  Eigen::Vector3i from, to;
  for (int a = 0; a < 3; ++a) {
    from[a] = std::max(0, static_cast<int>(std::floor(lo[a])));
    to[a] = std::min(g.dims[a] - 1, static_cast<int>(std::ceil(hi[a])));
  }
  // A voxel's extent along the axis: half of Σ |axis · edge|.
  const Eigen::Matrix3d edges = g.direction * g.spacing_mm.asDiagonal();
  const double half = 0.5 * (edges.transpose() * axis).cwiseAbs().sum();
  struct Sample {
    double t, hu;
    Eigen::Vector3d across;
  };
  std::vector<Sample> tube;
  std::vector<double> ring;
  for (int k = from.z(); k <= to.z(); ++k)
    for (int j = from.y(); j <= to.y(); ++j)
      for (int i = from.x(); i <= to.x(); ++i) {
        const Eigen::Vector3d d = g.toLps(Eigen::Vector3d(i, j, k)) - origin;
        const double t = d.dot(axis);
        if (t < t_lo || t > t_hi) continue;
        const Eigen::Vector3d across = d - t * axis;
        const double r = across.norm();
        const double hu = volume.valueAt(i, j, k);
        if (r <= ring_in) {
          tube.push_back({t, hu, across});
        } else if (r <= ring_out) {
          ring.push_back(hu);
        }
      }
  TipFit fit;
  if (tube.empty() || ring.empty()) return fit;
  fit.background_hu = medianOf(ring);
  const double voxel_mm3 = g.spacing_mm.prod();
  double plateau = 0.0, tail = 0.0, spread = 0.0, spread_w = 0.0;
  for (const auto& s : tube) {
    const double w = (s.hu - fit.background_hu) * voxel_mm3;
    const double in_plateau = shareWithin(s.t, half, t_ref - search.plateau_mm, t_ref);
    plateau += w * in_plateau;
    tail += w * shareWithin(s.t, half, t_ref, std::numeric_limits<double>::infinity());
    if (in_plateau > 0.0 && s.hu >= search.min_hu) {
      spread += w * in_plateau * s.across.squaredNorm();
      spread_w += w * in_plateau;
    }
  }
  fit.metal_per_mm = plateau / search.plateau_mm;
  if (!(fit.metal_per_mm > 0.0) || !(spread_w > 0.0)) return fit;
  const double tip_t = t_ref + tail / fit.metal_per_mm;
  fit.diameter_mm = std::sqrt(8.0 * spread / spread_w);  // a disc of radius r: E[ρ²] = r²/2
  // Across the axis: a parabola in t through the metal from kLateralFit_mm before the reference
  // point up to the tip, per direction across, read at the tip (a circular stylet sags t²/2R off
  // its tangent: a line would miss the tip of a curved one by ~0.2 mm). Every voxel of the tube
  // weighed by its metal, signed: the partial volume and the noise then average out instead of
  // pulling the centre towards the voxels that happen to pass a threshold.
  const Eigen::Vector3d any =
      std::abs(axis.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d e1 = axis.cross(any).normalized(), e2 = axis.cross(e1);
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Matrix<double, 3, 2> rhs = Eigen::Matrix<double, 3, 2>::Zero();
  for (const auto& s : tube) {
    // Soft ends (each voxel's share of the window), so the window's edges do not alias.
    const double share = shareWithin(s.t, half, t_ref - kLateralFit_mm, tip_t);
    if (share <= 0.0) continue;
    const double w = share * (s.hu - fit.background_hu);
    const double u = s.t - t_ref;
    const Eigen::Vector3d basis(1.0, u, u * u);
    normal += w * basis * basis.transpose();
    rhs.col(0) += w * basis * s.across.dot(e1);
    rhs.col(1) += w * basis * s.across.dot(e2);
  }
  const Eigen::Matrix<double, 3, 2> coef = normal.ldlt().solve(rhs);
  if (!coef.allFinite()) return fit;
  const double u = tip_t - t_ref;
  const Eigen::Vector3d at(1.0, u, u * u), slope(0.0, 1.0, 2.0 * u);
  fit.tip = origin + tip_t * axis + e1 * at.dot(coef.col(0)) + e2 * at.dot(coef.col(1));
  fit.direction = (axis + e1 * slope.dot(coef.col(0)) + e2 * slope.dot(coef.col(1))).normalized();
  fit.reference_t = t_ref;
  fit.ok = fit.tip.allFinite() && fit.direction.allFinite();
  return fit;
}

}  // namespace

Expected<NeedleDetection> findNeedles(const volume::Volume& volume, const NeedleSearch& search) {
  if (auto ok = checkSearch(search); !ok) return ok.error();
  const auto& g = volume.geometry;
  auto found = findBrightGroups(volume, search.min_hu, search.max_bright_voxels, "needle search",
                                "the needle's intensity");
  if (!found) return found.error();
  const BrightGroups& groups = *found;
  const Eigen::Vector3d insertion = search.insertion_lps.normalized();
  NeedleDetection out;
  out.groups = groups.count();
  std::size_t too_wide = 0, no_tip = 0, across = 0;
  for (std::size_t q = 0; q < groups.count(); ++q) {
    std::vector<BrightVoxel> voxels;
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector3d hi = -lo, sum = Eigen::Vector3d::Zero();
    for (std::size_t e = groups.start[q]; e < groups.start[q + 1]; ++e) {
      const Eigen::Vector3i v = groups.voxel(e);
      const Eigen::Vector3d lps = g.toLps(v.cast<double>());
      voxels.push_back({lps, volume.valueAt(v.x(), v.y(), v.z())});
      lo = lo.cwiseMin(lps);
      hi = hi.cwiseMax(lps);
      sum += lps;
    }
    const double reach_mm = (hi - lo).norm();
    if (reach_mm < search.min_length_mm) continue;
    const Eigen::Vector3d centre = sum / static_cast<double>(voxels.size());
    const bool marker = std::any_of(search.markers_lps_mm.begin(), search.markers_lps_mm.end(),
                                    [&](const Eigen::Vector3d& m) {
                                      return (m - centre).norm() <= search.marker_exclusion_mm;
                                    });
    if (marker) continue;
    auto line = trackCentreline(voxels, insertion, search, reach_mm, g.spacing_mm.maxCoeff());
    if (line.size() < 4) {
      ++no_tip;
      continue;
    }
    {
      std::size_t k = 1;
      while (k + 1 < line.size() && (line[k] - line.front()).norm() < 10.0)
        ++k;
      const Eigen::Vector3d entry = (line[k] - line.front()).normalized();
      if (!(entry.dot(insertion) >= std::cos(search.max_entry_angle_deg * M_PI / 180.0))) {
        ++across;
        continue;
      }
    }
    // The axis at the end from the centreline a few steps back; the end as thresholded.
    Eigen::Vector3d axis = (line.back() - line[line.size() - 4]).normalized();
    Eigen::Vector3d origin = line.back();
    TipFit fit;
    for (int pass = 0; pass < 2; ++pass) {  // the second along the first's direction at the tip
      double end_t = -std::numeric_limits<double>::infinity();
      for (const auto& v : voxels) {
        const Eigen::Vector3d d = v.lps_mm - origin;
        const double t = d.dot(axis);
        if ((d - t * axis).norm() <= search.tube_radius_mm) end_t = std::max(end_t, t);
      }
      fit = fitTip(volume, search, origin, axis, end_t);
      if (!fit.ok) break;
      origin = fit.tip;
      axis = fit.direction;
    }
    if (!fit.ok) {
      ++no_tip;
      continue;
    }
    if (fit.diameter_mm > search.max_diameter_mm) {
      ++too_wide;
      continue;
    }
    FoundNeedle needle;
    needle.tip_lps_mm = fit.tip;
    needle.direction_lps = fit.direction;
    // The tracked centroids up to the reference point (those past it straddle the tip), each
    // moved to the metal's centroid around it.
    for (const auto& p : refineCentreline(volume, line, search.tube_radius_mm)) {
      if ((p - fit.tip).dot(fit.direction) <= -kReferenceBack_mm + 0.5 * search.step_mm)
        needle.centreline_lps_mm.push_back(p);
    }
    needle.centreline_lps_mm.push_back(fit.tip);
    for (std::size_t i = 1; i < needle.centreline_lps_mm.size(); ++i)
      needle.visible_length_mm +=
          (needle.centreline_lps_mm[i] - needle.centreline_lps_mm[i - 1]).norm();
    needle.metal_per_mm = fit.metal_per_mm;
    needle.tip_diameter_mm = fit.diameter_mm;
    needle.background_hu = fit.background_hu;
    out.needles.push_back(std::move(needle));
  }
  std::sort(out.needles.begin(), out.needles.end(), [&](const auto& a, const auto& b) {
    return a.tip_lps_mm.dot(insertion) > b.tip_lps_mm.dot(insertion);
  });
  out.summary = fmt::format("{} needle{} found in {} bright groups", out.needles.size(),
                            out.needles.size() == 1 ? "" : "s", out.groups);
  if (too_wide + no_tip + across > 0) {
    out.summary += fmt::format(
        " ({} long group{} too wide for a needle, {} without a clear tip, {} not along the "
        "insertion)",
        too_wide, too_wide == 1 ? "" : "s", no_tip, across);
  }
  return out;
}

}  // namespace ignav::verification
