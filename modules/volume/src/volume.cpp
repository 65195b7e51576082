#include "ignav/volume/volume.hpp"

#include <sys/mman.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>
#include <sstream>

namespace ignav::volume {

namespace {
constexpr std::size_t kHugePage = std::size_t{2} << 20;
constexpr std::size_t kHugeThreshold = 2 * kHugePage;  // smaller blocks: plain new
}  // namespace

void* allocateVoxelMemory(std::size_t bytes) {
  if (bytes < kHugeThreshold) return ::operator new(bytes);
  const std::size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  void* p = std::aligned_alloc(kHugePage, rounded);
  if (p == nullptr) throw std::bad_alloc();
  madvise(p, rounded, MADV_HUGEPAGE);  // a hint: without THP it is simply ignored
  return p;
}

void freeVoxelMemory(void* p, std::size_t bytes) noexcept {
  if (bytes < kHugeThreshold) {
    ::operator delete(p);
  } else {
    std::free(p);
  }
}

Eigen::Matrix4d Geometry::ijkToLps() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = direction * spacing_mm.asDiagonal();
  m.topRightCorner<3, 1>() = origin_lps_mm;
  return m;
}

Eigen::Matrix4d Geometry::lpsToIjk() const {
  // direction is orthonormal: invert without a general solve.
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  const Eigen::Matrix3d inv = spacing_mm.cwiseInverse().asDiagonal() * direction.transpose();
  m.topLeftCorner<3, 3>() = inv;
  m.topRightCorner<3, 1>() = -inv * origin_lps_mm;
  return m;
}

Eigen::Vector3d Geometry::toLps(const Eigen::Vector3d& ijk) const {
  return origin_lps_mm + direction * spacing_mm.cwiseProduct(ijk);
}

Eigen::Vector3d Geometry::toIjk(const Eigen::Vector3d& lps_mm) const {
  return (direction.transpose() * (lps_mm - origin_lps_mm)).cwiseQuotient(spacing_mm);
}

double Geometry::outsideBy_mm(const Eigen::Vector3d& lps_mm) const {
  // The direction is orthonormal, so the excess along each voxel axis, in mm, is a component of
  // the distance to the box.
  const Eigen::Vector3d ijk = toIjk(lps_mm);
  double squared = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double low = -0.5, high = dims[static_cast<std::size_t>(a)] - 0.5;
    const double excess = ijk[a] < low ? low - ijk[a] : ijk[a] > high ? ijk[a] - high : 0.0;
    squared += excess * spacing_mm[a] * excess * spacing_mm[a];
  }
  return std::sqrt(squared);
}

std::size_t Geometry::voxelCount() const {
  return static_cast<std::size_t>(std::max(0, dims[0])) *
         static_cast<std::size_t>(std::max(0, dims[1])) *
         static_cast<std::size_t>(std::max(0, dims[2]));
}

Status Geometry::validate(const std::string& what) const {
  std::ostringstream m;
  m << what << ": ";
  if (dims[0] <= 0 || dims[1] <= 0 || dims[2] <= 0) {
    m << "dimensions " << dims[0] << " x " << dims[1] << " x " << dims[2] << " must be positive";
    return makeError(ErrorCode::kFormat, m.str());
  }
  if (voxelCount() > kMaxVoxels) {
    m << "dimensions " << dims[0] << " x " << dims[1] << " x " << dims[2] << " exceed the limit of "
      << kMaxVoxels << " voxels";
    return makeError(ErrorCode::kFormat, m.str());
  }
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(spacing_mm[a]) || spacing_mm[a] <= 0.0) {
      m << "spacing along axis "
        << "ijk"[a] << " is " << spacing_mm[a] << " mm; must be positive";
      return makeError(ErrorCode::kFormat, m.str());
    }
  }
  if (!origin_lps_mm.allFinite() || !direction.allFinite()) {
    m << "origin or direction has a non-finite value";
    return makeError(ErrorCode::kFormat, m.str());
  }
  const Eigen::Matrix3d gram = direction.transpose() * direction;
  const double off = (gram - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (off > 1e-4) {
    m << "direction cosines are not orthonormal (|DᵀD - I| = " << off << ")";
    return makeError(ErrorCode::kFormat, m.str());
  }
  return Ok{};
}

double Volume::sampleIjk(const Eigen::Vector3d& p, double outside) const {
  const auto raw =
      trilinear(geometry.dims, p, [this](int i, int j, int k) { return voxels[index(i, j, k)]; });
  return raw ? *raw * value_scale + value_offset : outside;
}

std::pair<double, double> Volume::valueRange() const {
  if (voxels.empty()) return {0.0, 0.0};
  const auto [lo, hi] = std::minmax_element(voxels.begin(), voxels.end());
  const double a = *lo * value_scale + value_offset, b = *hi * value_scale + value_offset;
  return {std::min(a, b), std::max(a, b)};
}

}  // namespace ignav::volume
