// Slice resampling: one plane through the volume, sampled trilinearly at pixel centres.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

#include <Eigen/Geometry>

#include "ignav/volume/slice.hpp"

namespace ignav::volume {
namespace {

Error invalid(const std::string& message) {
  return makeError(ErrorCode::kInvalidArgument, "reslice: " + message);
}

std::string str(const Eigen::Vector3d& v) {
  std::ostringstream o;
  o << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return o.str();
}

// Spacing of the volume axis best aligned with `w`: the natural sampling step along w.
double spacingAlong(const Geometry& g, const Eigen::Vector3d& w) {
  int best = 0;
  for (int a = 1; a < 3; ++a) {
    if (std::abs(g.direction.col(a).dot(w)) > std::abs(g.direction.col(best).dot(w))) best = a;
  }
  return g.spacing_mm[best];
}

// Half the extent of the voxel-centre box projected on `w`, measured from `centre`.
double halfExtentAlong(const Geometry& g, const Eigen::Vector3d& centre, const Eigen::Vector3d& w) {
  double half = 0.0;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d ijk((c & 1) ? g.dims[0] - 1 : 0, (c & 2) ? g.dims[1] - 1 : 0,
                              (c & 4) ? g.dims[2] - 1 : 0);
    half = std::max(half, std::abs((g.toLps(ijk) - centre).dot(w)));
  }
  return half;
}

Expected<int> sideLength(int requested, double half_extent_mm, double pixel_mm, const char* name) {
  if (requested == 0) {
    const double n = 2.0 * std::ceil(half_extent_mm / pixel_mm - 1e-9) + 1.0;
    return static_cast<int>(std::clamp(n, 1.0, static_cast<double>(kMaxSlicePixels)));
  }
  if (requested < 0 || requested > kMaxSlicePixels) {
    return invalid(std::string(name) + " " + std::to_string(requested) + " px is outside 1.." +
                   std::to_string(kMaxSlicePixels));
  }
  return requested;
}

}  // namespace

Eigen::Vector3d Slice::pixelToLps(double u, double v) const {
  return (pixel_to_lps * Eigen::Vector4d(u, v, 0.0, 1.0)).head<3>();
}

Eigen::Vector3d Slice::lpsToPixel(const Eigen::Vector3d& lps_mm) const {
  // The first three columns are orthogonal, so project instead of inverting.
  const Eigen::Vector3d d = lps_mm - pixel_to_lps.block<3, 1>(0, 3);
  const Eigen::Vector3d a = pixel_to_lps.block<3, 1>(0, 0), b = pixel_to_lps.block<3, 1>(0, 1),
                        n = pixel_to_lps.block<3, 1>(0, 2);
  return {a.dot(d) / a.squaredNorm(), b.dot(d) / b.squaredNorm(), n.dot(d) / n.squaredNorm()};
}

Eigen::Vector3d volumeCentreLps(const Geometry& geometry) {
  const Eigen::Vector3d mid((geometry.dims[0] - 1) / 2.0, (geometry.dims[1] - 1) / 2.0,
                            (geometry.dims[2] - 1) / 2.0);
  return geometry.toLps(mid);
}

Expected<Slice> reslice(const Volume& volume, const SliceSpec& spec) {
  const Geometry& g = volume.geometry;
  if (auto s = g.validate("reslice: volume"); !s.ok()) return s.error();
  if (volume.voxels.size() != g.voxelCount()) {
    return invalid("volume holds " + std::to_string(volume.voxels.size()) +
                   " voxels, its geometry declares " + std::to_string(g.voxelCount()));
  }
  if (!spec.centre_lps_mm.allFinite()) {
    return invalid("centre " + str(spec.centre_lps_mm) + " is not finite");
  }
  Eigen::Vector3d u_dir = Eigen::Vector3d::UnitX(), v_dir = Eigen::Vector3d::UnitY();
  switch (spec.view) {
    case View::kAxial:
      u_dir = Eigen::Vector3d::UnitX(), v_dir = Eigen::Vector3d::UnitY();
      break;
    case View::kCoronal:
      u_dir = Eigen::Vector3d::UnitX(), v_dir = -Eigen::Vector3d::UnitZ();
      break;
    case View::kSagittal:
      u_dir = Eigen::Vector3d::UnitY(), v_dir = -Eigen::Vector3d::UnitZ();
      break;
    case View::kOblique:
      if (!spec.oblique_u || !spec.oblique_v)
        return invalid("oblique view needs both u and v axes");
      u_dir = *spec.oblique_u, v_dir = *spec.oblique_v;
      if (!u_dir.allFinite() || !v_dir.allFinite() || std::abs(u_dir.norm() - 1.0) > 1e-6 ||
          std::abs(v_dir.norm() - 1.0) > 1e-6) {
        return invalid("oblique axes u " + str(u_dir) + " and v " + str(v_dir) +
                       " must be unit vectors (within 1e-6)");
      }
      if (std::abs(u_dir.dot(v_dir)) > 1e-6) {
        return invalid("oblique axes u " + str(u_dir) + " and v " + str(v_dir) +
                       " are not orthogonal (u.v = " + std::to_string(u_dir.dot(v_dir)) + ")");
      }
      break;
  }
  const Eigen::Vector3d normal = u_dir.cross(v_dir);

  double pixel_mm = spec.pixel_size_mm;
  if (pixel_mm == 0.0) pixel_mm = std::min(spacingAlong(g, u_dir), spacingAlong(g, v_dir));
  if (!std::isfinite(pixel_mm) || pixel_mm <= 0.0) {
    return invalid("pixel size " + std::to_string(spec.pixel_size_mm) + " mm must be positive");
  }
  double thickness_mm = spec.thickness_mm;
  if (thickness_mm == 0.0) thickness_mm = spacingAlong(g, normal);
  if (!std::isfinite(thickness_mm) || thickness_mm <= 0.0) {
    return invalid("thickness " + std::to_string(spec.thickness_mm) + " mm must be positive");
  }
  const auto width =
      sideLength(spec.width_px, halfExtentAlong(g, spec.centre_lps_mm, u_dir), pixel_mm, "width");
  if (!width) return width.error();
  const auto height =
      sideLength(spec.height_px, halfExtentAlong(g, spec.centre_lps_mm, v_dir), pixel_mm, "height");
  if (!height) return height.error();

  Slice slice;
  slice.width = *width;
  slice.height = *height;
  slice.pixel_size_mm = pixel_mm;
  slice.thickness_mm = thickness_mm;
  slice.window = spec.window;
  slice.view = spec.view;
  const Eigen::Vector3d origin = spec.centre_lps_mm - 0.5 * (slice.width - 1) * pixel_mm * u_dir -
                                 0.5 * (slice.height - 1) * pixel_mm * v_dir;
  slice.pixel_to_lps.setIdentity();
  slice.pixel_to_lps.block<3, 1>(0, 0) = pixel_mm * u_dir;
  slice.pixel_to_lps.block<3, 1>(0, 1) = pixel_mm * v_dir;
  slice.pixel_to_lps.block<3, 1>(0, 2) = normal;
  slice.pixel_to_lps.block<3, 1>(0, 3) = origin;

  // Pixel -> IJK is affine: step along rows and columns in index space.
  const Eigen::Matrix4d to_ijk = g.lpsToIjk() * slice.pixel_to_lps;
  const Eigen::Vector3d ijk0 = to_ijk.block<3, 1>(0, 3), du = to_ijk.block<3, 1>(0, 0),
                        dv = to_ijk.block<3, 1>(0, 1);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  slice.values.resize(static_cast<std::size_t>(slice.width) * slice.height);
  for (int v = 0; v < slice.height; ++v) {
    const Eigen::Vector3d row = ijk0 + v * dv;
    for (int u = 0; u < slice.width; ++u) {
      const double s = volume.sampleIjk(row + u * du, nan);
      slice.values[static_cast<std::size_t>(v) * slice.width + u] =
          std::isnan(s) ? spec.outside : static_cast<float>(s);
    }
  }
  return slice;
}

std::string directionLetters(const Eigen::Vector3d& direction_lps) {
  const Eigen::Vector3d d = direction_lps.normalized();
  std::array<int, 3> order{0, 1, 2};
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return std::abs(d[a]) > std::abs(d[b]); });
  static const char kPositive[] = "LPS", kNegative[] = "RAI";
  std::string letters;
  for (int a : order) {
    if (letters.empty() || std::abs(d[a]) > 0.1) {
      letters += d[a] >= 0.0 ? kPositive[a] : kNegative[a];
    }
  }
  return letters;
}

EdgeLabels orientationLabels(const Slice& slice) {
  const Eigen::Vector3d u = slice.pixel_to_lps.block<3, 1>(0, 0);
  const Eigen::Vector3d v = slice.pixel_to_lps.block<3, 1>(0, 1);
  return {directionLetters(-u), directionLetters(u), directionLetters(-v), directionLetters(v)};
}

}  // namespace ignav::volume
