// Resampled 2D slices of a Volume in radiological display convention, with the exact pixel <->
// LPS mapping a point-and-click client needs.
//
// Pixel (u, v): u = column (to the right), v = row (downwards); integer values are pixel centres.
// Display conventions (as 3D Slicer shows them; +u = image right, +v = image down, in LPS):
//   axial    (seen from the feet):        +u = +L (x), +v = +P (y);  labels R | L, A top, P bottom
//   coronal  (seen from the front):       +u = +L (x), +v = -S (-z); labels R | L, S top, I bottom
//   sagittal (seen from patient's left):  +u = +P (y), +v = -S (-z); labels A | P, S top, I bottom
//   oblique: +u and +v are the caller's unit vectors.
// The plane normal n = u x v points away from the viewer (axial +S, coronal +P, sagittal -L).
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::volume {

enum class View { kAxial, kSagittal, kCoronal, kOblique };

// Display window in physical units (HU for CT): [level - width/2, level + width/2] -> black..white.
struct WindowLevel {
  double width = 400.0;
  double level = 40.0;
};
// Standard CT presets (Radiopaedia "windowing (CT)"): bone W1800/L400, soft tissue W400/L40,
// lung W1500/L-600.
constexpr WindowLevel kWindowBone{1800.0, 400.0};
constexpr WindowLevel kWindowSoftTissue{400.0, 40.0};
constexpr WindowLevel kWindowLung{1500.0, -600.0};

struct SliceSpec {
  View view = View::kAxial;
  Eigen::Vector3d centre_lps_mm = Eigen::Vector3d::Zero();  // lands on the central pixel
  // Oblique only: in-plane axes (+u, +v), LPS unit vectors, orthogonal.
  std::optional<Eigen::Vector3d> oblique_u, oblique_v;
  int width_px = 0;  // 0: fit the whole volume (at most kMaxSlicePixels per side)
  int height_px = 0;
  double pixel_size_mm = 0.0;  // 0: the volume's finest spacing along u and v
  double thickness_mm = 0.0;   // 0: the voxel extent along the normal (for overlays)
  WindowLevel window = kWindowSoftTissue;
  float outside = std::numeric_limits<float>::quiet_NaN();  // value beyond the volume
};
constexpr int kMaxSlicePixels = 4096;

struct Slice {
  int width = 0, height = 0;
  std::vector<float> values;  // physical values, row-major (v * width + u)
  // LPS = pixel_to_lps * (u, v, d, 1): columns are pixel_size * u_dir, pixel_size * v_dir, the
  // unit normal (d = signed distance from the plane, mm) and the LPS of pixel (0, 0).
  Eigen::Matrix4d pixel_to_lps = Eigen::Matrix4d::Identity();
  double pixel_size_mm = 1.0;
  double thickness_mm = 1.0;
  WindowLevel window;
  View view = View::kAxial;

  float at(int u, int v) const { return values[static_cast<std::size_t>(v) * width + u]; }
  Eigen::Vector3d pixelToLps(double u, double v) const;
  // (u, v, signed distance from the plane in mm along the normal).
  Eigen::Vector3d lpsToPixel(const Eigen::Vector3d& lps_mm) const;
};

Expected<Slice> reslice(const Volume& volume, const SliceSpec& spec);

// The LPS centre of the voxel-centre box, a natural default for SliceSpec::centre_lps_mm.
Eigen::Vector3d volumeCentreLps(const Geometry& geometry);

// Patient-direction letters at the four image edges, derived from the mapping (so oblique
// slices get e.g. "LA"): the dominant letter first, then any other component above 0.1.
struct EdgeLabels {
  std::string left, right, top, bottom;
};
EdgeLabels orientationLabels(const Slice& slice);
// Letters for one LPS direction: +x L, -x R, +y P, -y A, +z S, -z I.
std::string directionLetters(const Eigen::Vector3d& direction_lps);

}  // namespace ignav::volume
