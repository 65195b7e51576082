#include "ignav/kinematics/reachable_region.hpp"

#include <algorithm>
#include <cmath>

namespace ignav::kinematics {

namespace {
constexpr int kIntervals = 4096;
constexpr double kRadiusBand_mm = 1e-6;  // inverse() decides this close to r_min and r_max
}  // namespace

ReachableRegion::ReachableRegion(const Kinematics& kinematics)
    : kinematics_(kinematics),
      r_min_mm_(kinematics.minRadius_mm()),
      r_max_mm_(kinematics.maxRadius_mm()),
      zc_max_mm_(kinematics.instrument().cannula_travel_mm) {
  step_mm_ = (r_max_mm_ - r_min_mm_) / kIntervals;
  auto depthAt = [&](double r) {
    return kinematics_.tipDepthAtHome_mm(kinematics_.styletForRadius_mm(r));
  };
  depth_mm_.resize(kIntervals + 1);
  for (int i = 0; i <= kIntervals; ++i)
    depth_mm_[static_cast<std::size_t>(i)] = depthAt(r_min_mm_ + i * step_mm_);
  // The interpolation's error, measured inside each interval at its quarters, sets the band
  // around the depth limits that inverse() decides there: four times it, and never under a
  // nanometre. Near r_min the depth is steep (the radius barely grows as the stylet starts to
  // leave the cannula), and the first few intervals are left to inverse() almost whole.
  band_mm_.resize(kIntervals);
  for (int i = 0; i < kIntervals; ++i) {
    const auto k = static_cast<std::size_t>(i);
    double worst = 0.0;
    for (double t : {0.25, 0.5, 0.75}) {
      const double table = depth_mm_[k] + t * (depth_mm_[k + 1] - depth_mm_[k]);
      worst = std::max(worst, std::abs(table - depthAt(r_min_mm_ + (i + t) * step_mm_)));
    }
    band_mm_[k] = std::max(4.0 * worst, kRadiusBand_mm);
  }
  const auto [lo, hi] = std::minmax_element(depth_mm_.begin(), depth_mm_.end());
  depth_lo_mm_ = *lo;
  depth_hi_mm_ = *hi;
}

bool ReachableRegion::exactly(const Eigen::Vector3d& p) const {
  const auto s = kinematics_.inverse(p);
  return s.ok() && s->reachable();
}

bool ReachableRegion::contains(const Eigen::Vector3d& p) const {
  if (!p.allFinite()) return false;
  const double r = std::sqrt(p.x() * p.x() + p.y() * p.y());
  if (r < r_min_mm_ - kRadiusBand_mm || r > r_max_mm_ + kRadiusBand_mm) return false;
  if (r < r_min_mm_ + kRadiusBand_mm || r > r_max_mm_ - kRadiusBand_mm || step_mm_ <= 0.0) {
    return exactly(p);
  }
  const double x = (r - r_min_mm_) / step_mm_;
  const auto i = std::min(static_cast<std::size_t>(x), band_mm_.size() - 1);
  const double t = x - static_cast<double>(i);
  const double depth = depth_mm_[i] + t * (depth_mm_[i + 1] - depth_mm_[i]);
  const double zc = depth - p.z();  // the cannula travel that puts the tip at this depth
  const double band = band_mm_[i];
  if (zc < -band || zc > zc_max_mm_ + band) return false;
  if (zc < band || zc > zc_max_mm_ - band) return exactly(p);
  return true;
}

double ReachableRegion::widestBand_mm() const {
  return *std::max_element(band_mm_.begin(), band_mm_.end());
}

double ReachableRegion::tableShare() const {
  std::size_t narrow = 0;
  for (double b : band_mm_)
    narrow += b < 1e-3;
  return static_cast<double>(narrow) / static_cast<double>(band_mm_.size());
}

std::array<Eigen::Vector3d, 8> ReachableRegion::boundingBox() const {
  const double r = r_max_mm_ + 1.0, z_lo = depth_lo_mm_ - zc_max_mm_ - 1.0,
               z_hi = depth_hi_mm_ + 1.0;
  std::array<Eigen::Vector3d, 8> corners;
  for (int c = 0; c < 8; ++c) {
    corners[static_cast<std::size_t>(c)] =
        Eigen::Vector3d(c & 1 ? r : -r, c & 2 ? r : -r, c & 4 ? z_hi : z_lo);
  }
  return corners;
}

}  // namespace ignav::kinematics
