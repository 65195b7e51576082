// A CT volume: voxels stored once as int16 with a linear value mapping, and one geometry type
// that maps voxel indices (IJK) to patient coordinates (LPS, mm), as DICOM, NRRD and 3D Slicer
// define them.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"

namespace ignav::volume {

// Voxel (i, j, k) centre -> LPS: origin + direction * diag(spacing) * (i, j, k).
// direction's columns are the unit i, j and k axes in LPS (DICOM: row direction, column
// direction, slice normal), so it is orthonormal; its determinant may be -1.
struct Geometry {
  std::array<int, 3> dims{0, 0, 0};
  Eigen::Vector3d spacing_mm = Eigen::Vector3d::Ones();
  Eigen::Vector3d origin_lps_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d direction = Eigen::Matrix3d::Identity();

  Eigen::Matrix4d ijkToLps() const;
  Eigen::Matrix4d lpsToIjk() const;
  Eigen::Vector3d toLps(const Eigen::Vector3d& ijk) const;
  Eigen::Vector3d toIjk(const Eigen::Vector3d& lps_mm) const;
  std::size_t voxelCount() const;
  // How far an LPS point lies outside the imaged box (every voxel with its half-voxel margin, as
  // DICOM's pixel spacing describes it): 0 inside or on its faces, else the distance in mm to the
  // nearest point of the box.
  double outsideBy_mm(const Eigen::Vector3d& lps_mm) const;
  // Dims positive, spacing finite and positive, origin finite, direction orthonormal
  // (columns unit length and mutually perpendicular within 1e-4). `what` names the source.
  Status validate(const std::string& what) const;
};

// Trilinear interpolation between the voxel centres of a grid of `dims` at a continuous IJK
// position, `at(i, j, k)` giving each voxel's value; none beyond the centres' hull (no
// extrapolation). Volume::sampleIjk's rule, for grids of other value types (a dose in float).
template <typename At>
std::optional<double> trilinear(const std::array<int, 3>& d, const Eigen::Vector3d& p,
                                const At& at) {
  if (!p.allFinite()) return std::nullopt;
  const double x = p.x(), y = p.y(), z = p.z();
  if (x < 0.0 || y < 0.0 || z < 0.0 || x > d[0] - 1 || y > d[1] - 1 || z > d[2] - 1) {
    return std::nullopt;
  }
  const int i0 = std::min(static_cast<int>(x), std::max(0, d[0] - 2));
  const int j0 = std::min(static_cast<int>(y), std::max(0, d[1] - 2));
  const int k0 = std::min(static_cast<int>(z), std::max(0, d[2] - 2));
  const int i1 = std::min(i0 + 1, d[0] - 1), j1 = std::min(j0 + 1, d[1] - 1),
            k1 = std::min(k0 + 1, d[2] - 1);
  const double fx = x - i0, fy = y - j0, fz = z - k0;
  const auto v = [&](int i, int j, int k) { return static_cast<double>(at(i, j, k)); };
  const double c00 = v(i0, j0, k0) * (1 - fx) + v(i1, j0, k0) * fx;
  const double c10 = v(i0, j1, k0) * (1 - fx) + v(i1, j1, k0) * fx;
  const double c01 = v(i0, j0, k1) * (1 - fx) + v(i1, j0, k1) * fx;
  const double c11 = v(i0, j1, k1) * (1 - fx) + v(i1, j1, k1) * fx;
  const double c0 = c00 * (1 - fy) + c10 * fy, c1 = c01 * (1 - fy) + c11 * fy;
  return c0 * (1 - fz) + c1 * fz;
}

// Voxel memory: large blocks are 2 MiB aligned and marked for transparent huge pages, so a
// 150 MB volume costs ~75 page faults instead of ~37,000 when a reader first writes it.
void* allocateVoxelMemory(std::size_t bytes);
void freeVoxelMemory(void* p, std::size_t bytes) noexcept;

// Leaves new elements uninitialised (resize / the size constructor): a 150 MB volume that is
// about to be overwritten by a reader is not zero-filled first. assign(n, value) still fills.
template <typename T>
struct UninitialisedAllocator {
  using value_type = T;
  UninitialisedAllocator() = default;
  template <typename U>
  UninitialisedAllocator(const UninitialisedAllocator<U>&) noexcept {}  // NOLINT: implicit
  T* allocate(std::size_t n) { return static_cast<T*>(allocateVoxelMemory(n * sizeof(T))); }
  void deallocate(T* p, std::size_t n) noexcept { freeVoxelMemory(p, n * sizeof(T)); }
  template <typename U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  friend bool operator==(const UninitialisedAllocator&, const UninitialisedAllocator&) {
    return true;
  }
  friend bool operator!=(const UninitialisedAllocator&, const UninitialisedAllocator&) {
    return false;
  }
};
using VoxelBuffer = std::vector<std::int16_t, UninitialisedAllocator<std::int16_t>>;

// Stored value v -> physical value (HU for CT): v * value_scale + value_offset. CT series with
// RescaleSlope 1 store HU directly (scale 1, offset 0).
class Volume {
 public:
  Geometry geometry;
  VoxelBuffer voxels;  // i fastest, then j, then k
  double value_scale = 1.0;
  double value_offset = 0.0;
  std::string modality;    // "CT", "MR", ... ("" when the file format has none)
  std::string series_uid;  // DICOM SeriesInstanceUID, or "" for NRRD/MetaImage
  // DICOM FrameOfReferenceUID: structures and registrations drawn in this frame belong here
  // ("" for NRRD/MetaImage, which carry none).
  std::string frame_of_reference_uid;
  // DICOM's study and patient: what exported objects (RT Dose, RT Plan) share with the CT so that
  // a DICOM browser files them together ("" for NRRD/MetaImage).
  std::string study_uid, patient_name, patient_id;
  std::string description;  // e.g. SeriesDescription or the file name

  std::size_t index(int i, int j, int k) const {
    return static_cast<std::size_t>(i) +
           static_cast<std::size_t>(geometry.dims[0]) *
               (static_cast<std::size_t>(j) +
                static_cast<std::size_t>(geometry.dims[1]) * static_cast<std::size_t>(k));
  }
  bool contains(int i, int j, int k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < geometry.dims[0] && j < geometry.dims[1] &&
           k < geometry.dims[2];
  }
  // Physical value of one voxel (no bounds check).
  double valueAt(int i, int j, int k) const {
    return voxels[index(i, j, k)] * value_scale + value_offset;
  }
  // Trilinear interpolation at a continuous IJK position; `outside` beyond the voxel centres'
  // hull (no extrapolation).
  double sampleIjk(const Eigen::Vector3d& ijk, double outside) const;
  double sampleLps(const Eigen::Vector3d& lps_mm, double outside) const {
    return sampleIjk(geometry.toIjk(lps_mm), outside);
  }
  // Physical min and max over all voxels.
  std::pair<double, double> valueRange() const;
};

// Progress of long loads, for the server to publish: a stage name ("scan", "decode"), work done
// and total (total 0 when unknown).
struct Progress {
  std::string stage;
  std::size_t done = 0;
  std::size_t total = 0;
};
using ProgressCallback = std::function<void(const Progress&)>;

// The largest volume any reader accepts, so a corrupt header cannot ask for 10 GB.
constexpr std::size_t kMaxVoxels = std::size_t{1} << 31;  // 4 GiB of int16

}  // namespace ignav::volume
