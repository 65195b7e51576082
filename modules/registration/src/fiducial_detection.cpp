#include "ignav/registration/fiducial_detection.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "bright_clusters.hpp"
#include "ignav/volume/threshold.hpp"

namespace ignav::registration {
namespace {

constexpr std::size_t kMaxModelPoints = 8;
constexpr std::size_t kMaxMatchCandidates = 32;  // bounds the search: 32·31·30 triples
constexpr std::size_t kMaxRejectedListed = 32;
constexpr int kShellVoxels = 2;   // partial-volume voxels around a cluster that still count
constexpr int kWindowVoxels = 4;  // background is sampled out to here

using Index3 = Eigen::Vector3i;

Status checkSearch(const FiducialSearch& s, const std::vector<Eigen::Vector3d>& model) {
  auto bad = [](const std::string& field, const std::string& why) {
    return makeError(ErrorCode::kInvalidArgument, "fiducial search: " + field + " " + why);
  };
  if (!std::isfinite(s.min_hu)) return bad("min_hu", "must be finite");
  if (!(s.min_volume_mm3 >= 0.0 && s.min_volume_mm3 <= s.max_volume_mm3) ||
      !std::isfinite(s.max_volume_mm3)) {
    return bad("volume range", fmt::format("[{:g}, {:g}] mm³ must be finite with 0 <= min <= max",
                                           s.min_volume_mm3, s.max_volume_mm3));
  }
  if (!(s.max_extent_mm > 0.0) || !std::isfinite(s.max_extent_mm)) {
    return bad("max_extent_mm", fmt::format("= {:g} must be positive", s.max_extent_mm));
  }
  if (!(s.min_match_margin_mm >= 0.0)) {
    return bad("min_match_margin_mm",
               fmt::format("= {:g} must not be negative", s.min_match_margin_mm));
  }
  if (!(s.max_match_residual_mm > 0.0)) {
    return bad("max_match_residual_mm",
               fmt::format("= {:g} must be positive", s.max_match_residual_mm));
  }
  if (s.expect < 1 || s.expect > kMaxModelPoints) {
    return bad("expect", fmt::format("= {} must be in [1, {}]", s.expect, kMaxModelPoints));
  }
  if (model.size() > kMaxModelPoints) {
    return bad("model points", fmt::format("{} given, at most {}", model.size(), kMaxModelPoints));
  }
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (!model[i].allFinite()) {
      return bad(fmt::format("model point {}", i + 1), "has a non-finite coordinate");
    }
  }
  return Ok{};
}

// The cluster's centroid weighted by HU above the local background, over the cluster and a
// shell of partial-volume voxels; the background is the median of the window around it.
void refineCentroid(const volume::Volume& volume, const std::vector<Index3>& voxels,
                    FiducialCandidate& candidate) {
  const auto& dims = volume.geometry.dims;
  Index3 lo = voxels.front();
  Index3 hi = voxels.front();
  for (const auto& v : voxels) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  const Index3 dims_v(dims[0], dims[1], dims[2]);
  const Index3 wlo = (lo.array() - kWindowVoxels).max(0).matrix();
  const Index3 whi = (hi.array() + kWindowVoxels).min(dims_v.array() - 1).matrix();
  const Index3 size = whi - wlo + Index3::Ones();
  auto local = [&](const Index3& v) {
    const Index3 d = v - wlo;
    return static_cast<std::size_t>(d.x()) +
           static_cast<std::size_t>(size.x()) *
               (static_cast<std::size_t>(d.y()) +
                static_cast<std::size_t>(size.y()) * static_cast<std::size_t>(d.z()));
  };
  // Chebyshev distance (in voxels) to the cluster, capped: 0 inside, 1..kShellVoxels in the
  // shell, more outside.
  std::vector<int> distance(static_cast<std::size_t>(size.prod()), kShellVoxels + 1);
  for (const auto& v : voxels) {
    for (int dz = -kShellVoxels; dz <= kShellVoxels; ++dz) {
      for (int dy = -kShellVoxels; dy <= kShellVoxels; ++dy) {
        for (int dx = -kShellVoxels; dx <= kShellVoxels; ++dx) {
          const Index3 n = v + Index3(dx, dy, dz);
          if ((n.array() < wlo.array()).any() || (n.array() > whi.array()).any()) continue;
          const int d = std::max({std::abs(dx), std::abs(dy), std::abs(dz)});
          int& slot = distance[local(n)];
          slot = std::min(slot, d);
        }
      }
    }
  }
  std::vector<double> outside;
  for (int k = wlo.z(); k <= whi.z(); ++k) {
    for (int j = wlo.y(); j <= whi.y(); ++j) {
      for (int i = wlo.x(); i <= whi.x(); ++i) {
        if (distance[local(Index3(i, j, k))] > kShellVoxels) {
          outside.push_back(volume.valueAt(i, j, k));
        }
      }
    }
  }
  double background = 0.0;
  if (!outside.empty()) {
    auto mid = outside.begin() + static_cast<std::ptrdiff_t>(outside.size() / 2);
    std::nth_element(outside.begin(), mid, outside.end());
    background = *mid;
  } else {
    background = std::numeric_limits<double>::infinity();
    for (int k = wlo.z(); k <= whi.z(); ++k) {
      for (int j = wlo.y(); j <= whi.y(); ++j) {
        for (int i = wlo.x(); i <= whi.x(); ++i) {
          background = std::min(background, volume.valueAt(i, j, k));
        }
      }
    }
  }
  Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
  double weight_sum = 0.0;
  for (int k = wlo.z(); k <= whi.z(); ++k) {
    for (int j = wlo.y(); j <= whi.y(); ++j) {
      for (int i = wlo.x(); i <= whi.x(); ++i) {
        if (distance[local(Index3(i, j, k))] > kShellVoxels) continue;
        const double w = volume.valueAt(i, j, k) - background;
        if (w <= 0.0) continue;
        weighted += w * Eigen::Vector3d(i, j, k);
        weight_sum += w;
      }
    }
  }
  candidate.background_hu = background;
  Eigen::Vector3d ijk = Eigen::Vector3d::Zero();
  if (weight_sum > 0.0) {
    ijk = weighted / weight_sum;
  } else {
    for (const auto& v : voxels)
      ijk += v.cast<double>();
    ijk /= static_cast<double>(voxels.size());
  }
  candidate.centroid_lps_mm = volume.geometry.toLps(ijk);
}

std::string describeCandidate(const FiducialCandidate& c) {
  return fmt::format("({:.2f}, {:.2f}, {:.2f})", c.centroid_lps_mm.x(), c.centroid_lps_mm.y(),
                     c.centroid_lps_mm.z());
}

}  // namespace

Expected<FiducialMatch> matchByDistances(const std::vector<Eigen::Vector3d>& candidates_mm,
                                         const std::vector<Eigen::Vector3d>& model_points_mm,
                                         double max_residual_mm, double min_margin_mm) {
  const std::size_t m = model_points_mm.size();
  const std::size_t n = std::min(candidates_mm.size(), kMaxMatchCandidates);
  if (m < 2 || m > kMaxModelPoints) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("matching needs 2 to {} model points, got {}", kMaxModelPoints, m));
  }
  if (n < m) {
    return makeError(
        ErrorCode::kDegenerate,
        fmt::format("{} bead-like candidates found, {} markers expected", candidates_mm.size(), m),
        "too_few_candidates");
  }
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  std::vector<double> model_distance;
  for (std::size_t a = 0; a < m; ++a) {
    for (std::size_t b = a + 1; b < m; ++b) {
      pairs.emplace_back(a, b);
      model_distance.push_back((model_points_mm[a] - model_points_mm[b]).norm());
    }
  }
  double best = std::numeric_limits<double>::infinity();
  double runner_up = std::numeric_limits<double>::infinity();
  std::vector<std::size_t> best_assignment;
  std::vector<std::size_t> assignment(m);
  std::vector<bool> used(n, false);
  // Depth-first over ordered selections; the partial sum of squares prunes branches that can
  // no longer beat the runner-up.
  auto search = [&](auto&& self, std::size_t depth, double sum_sq) -> void {
    if (sum_sq / static_cast<double>(pairs.size()) >= runner_up * runner_up) return;
    if (depth == m) {
      const double rms = std::sqrt(sum_sq / static_cast<double>(pairs.size()));
      if (rms < best) {
        runner_up = best;
        best = rms;
        best_assignment = assignment;
      } else {
        runner_up = std::min(runner_up, rms);
      }
      return;
    }
    for (std::size_t c = 0; c < n; ++c) {
      if (used[c]) continue;
      double added = 0.0;
      for (std::size_t a = 0; a < depth; ++a) {
        const double d = (candidates_mm[assignment[a]] - candidates_mm[c]).norm();
        const std::size_t pair = a * (2 * m - a - 1) / 2 + (depth - a - 1);
        added += (d - model_distance[pair]) * (d - model_distance[pair]);
      }
      used[c] = true;
      assignment[depth] = c;
      self(self, depth + 1, sum_sq + added);
      used[c] = false;
    }
  };
  search(search, 0, 0.0);
  if (!(best <= max_residual_mm)) {
    return makeError(
        ErrorCode::kDegenerate,
        fmt::format("no {} of the {} candidates match the model's mutual distances: best RMS "
                    "residual {:.2f} mm exceeds {:.2f} mm",
                    m, n, best, max_residual_mm),
        "no_match");
  }
  if (runner_up - best < min_margin_mm) {
    return makeError(ErrorCode::kDegenerate,
                     fmt::format("ambiguous: two assignments of the candidates fit the model's "
                                 "mutual distances almost equally ({:.2f} and {:.2f} mm RMS); "
                                 "confirm the markers by hand",
                                 best, runner_up),
                     "ambiguous_match");
  }
  FiducialMatch match;
  match.candidate = best_assignment;
  double sum_sq = 0.0;
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    const double d = (candidates_mm[best_assignment[pairs[p].first]] -
                      candidates_mm[best_assignment[pairs[p].second]])
                         .norm();
    match.distance_residuals_mm.push_back(std::abs(d - model_distance[p]));
    sum_sq += (d - model_distance[p]) * (d - model_distance[p]);
  }
  match.rms_residual_mm = std::sqrt(sum_sq / static_cast<double>(pairs.size()));
  match.runner_up_rms_mm = runner_up;
  return match;
}

Expected<FiducialDetection> findFiducials(const volume::Volume& volume,
                                          const FiducialSearch& search,
                                          const std::vector<Eigen::Vector3d>& model_points_mm) {
  if (auto ok = checkSearch(search, model_points_mm); !ok) return ok.error();
  if (auto ok = volume.geometry.validate("volume"); !ok) return ok.error();
  const auto& g = volume.geometry;
  if (volume.voxels.size() != g.voxelCount()) {
    return makeError(ErrorCode::kInvalidArgument, "volume: voxel buffer does not match its dims");
  }

  // Bright voxels, as integer IJK so that clustering at tolerance √3 is exactly
  // 26-connectivity whatever the spacing.
  // The threshold in stored units, so the scan over ~10^8 voxels is an int16 compare.
  // Most of a CT holds no marker: one vectorised pass finds the bright voxels.
  auto at_or_above = volume::voxelsAtOrAbove(volume, search.min_hu, search.max_bright_voxels);
  if (!at_or_above) {
    if (at_or_above.error().reason != "too_many_bright_voxels") return at_or_above.error();
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("fiducial search: more than {} voxels at or above "
                                 "min_hu {:g} HU; raise min_hu to the markers' intensity",
                                 search.max_bright_voxels, search.min_hu));
  }
  const std::size_t nx = static_cast<std::size_t>(g.dims[0]);
  const std::size_t nxy = nx * static_cast<std::size_t>(g.dims[1]);
  std::vector<Index3> bright;
  bright.reserve(at_or_above->size());
  for (const std::size_t idx : *at_or_above) {
    bright.emplace_back(static_cast<int>(idx % nx), static_cast<int>((idx % nxy) / nx),
                        static_cast<int>(idx / nxy));
  }
  FiducialDetection result;
  result.bright_voxels = bright.size();
  std::vector<Eigen::Vector3f> points;
  points.reserve(bright.size());
  for (const auto& v : bright)
    points.push_back(v.cast<float>());
  const auto clusters = detail::euclideanClusters(points, std::sqrt(3.0) + 0.01);

  const double voxel_mm3 = g.spacing_mm.prod();
  std::size_t rejected_omitted = 0;
  std::vector<Eigen::Vector3d> accepted_positions;
  std::vector<std::size_t> accepted_index;
  for (const auto& cluster : clusters) {
    std::vector<Index3> voxels;
    voxels.reserve(cluster.size());
    for (std::size_t p : cluster)
      voxels.push_back(bright[p]);
    FiducialCandidate c;
    c.voxel_count = voxels.size();
    c.volume_mm3 = static_cast<double>(voxels.size()) * voxel_mm3;
    Index3 lo = voxels.front();
    Index3 hi = voxels.front();
    c.peak_hu = -std::numeric_limits<double>::infinity();
    for (const auto& v : voxels) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
      c.peak_hu = std::max(c.peak_hu, volume.valueAt(v.x(), v.y(), v.z()));
    }
    c.extent_mm = ((hi - lo + Index3::Ones()).cast<double>().cwiseProduct(g.spacing_mm)).maxCoeff();
    if (c.volume_mm3 < search.min_volume_mm3) {
      c.rejected = fmt::format("too small: {:.2f} mm³ < {:g} mm³ (noise or a speck)", c.volume_mm3,
                               search.min_volume_mm3);
    } else if (c.volume_mm3 > search.max_volume_mm3) {
      c.rejected = fmt::format("too large: {:.1f} mm³ > {:g} mm³ (bone, a rod or the needle)",
                               c.volume_mm3, search.max_volume_mm3);
    } else if (c.extent_mm > search.max_extent_mm) {
      c.rejected = fmt::format("too long: {:.1f} mm > {:g} mm (not a bead)", c.extent_mm,
                               search.max_extent_mm);
    }
    if (!c.rejected.empty()) {
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (const auto& v : voxels)
        mean += v.cast<double>();
      c.centroid_lps_mm = g.toLps(mean / static_cast<double>(voxels.size()));
      if (result.candidates.size() - accepted_index.size() >= kMaxRejectedListed) {
        ++rejected_omitted;
        continue;
      }
    } else {
      refineCentroid(volume, voxels, c);
      accepted_index.push_back(result.candidates.size());
      accepted_positions.push_back(c.centroid_lps_mm);
    }
    result.candidates.push_back(std::move(c));
  }

  std::string found = fmt::format(
      "{} bright voxels at or above {:g} HU in {} clusters; {} "
      "bead-like",
      bright.size(), search.min_hu, clusters.size(), accepted_positions.size());
  if (rejected_omitted > 0)
    found += fmt::format(" ({} more rejected clusters not listed)", rejected_omitted);
  if (!model_points_mm.empty()) {
    auto match = matchByDistances(accepted_positions, model_points_mm, search.max_match_residual_mm,
                                  search.min_match_margin_mm);
    if (match) {
      for (auto& c : match->candidate)
        c = accepted_index[c];
      result.summary = fmt::format(
          "{}. Matched {} markers by mutual distances: RMS residual {:.3f} mm (next-best "
          "assignment {:.3f} mm)",
          found, model_points_mm.size(), match->rms_residual_mm, match->runner_up_rms_mm);
      result.match = std::move(match).value();
    } else {
      result.summary = found + ". " + match.error().message;
    }
  } else if (accepted_positions.size() == search.expect) {
    FiducialMatch chosen;
    chosen.candidate = accepted_index;
    chosen.runner_up_rms_mm = std::numeric_limits<double>::infinity();
    result.match = std::move(chosen);
    result.summary = found + fmt::format(", as many as expected ({})", search.expect);
  } else if (accepted_positions.size() > search.expect) {
    result.summary = found + fmt::format(
                                 ", {} expected: give model points (the robot config) "
                                 "to choose by mutual distances",
                                 search.expect);
  } else {
    result.summary = found + fmt::format(
                                 ", {} expected: lower min_hu, or check that the markers "
                                 "are in the scan",
                                 search.expect);
  }
  if (result.match) {
    std::string at;
    for (std::size_t idx : result.match->candidate) {
      at += (at.empty() ? "" : ", ") + describeCandidate(result.candidates[idx]);
    }
    result.summary += "; at " + at + " mm (LPS)";
  }
  return result;
}

}  // namespace ignav::registration
