// Point-based image -> robot registration (MODEL.md §9): least-squares similarity (or rigid)
// from N >= 3 point pairs, its fiducial registration error (FRE), and the expected target
// registration error (TRE) anywhere after Fitzpatrick & West (1998). Values in, values out.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"

namespace ignav::registration {

// Similarity estimates rotation, translation and one isotropic scale (the paper's choice);
// rigid fixes the scale at 1.
enum class TransformKind { kSimilarity, kRigid };
const char* toString(TransformKind kind);  // "similarity" | "rigid"

// What a point set must satisfy before it may steer a needle. A rejection's Error carries one
// of these reason tokens: too_few_pairs, count_mismatch, non_finite, out_of_range (beyond
// 10^6 mm), coincident, collinear, scale_out_of_range, fre_too_large.
struct RegistrationLimits {
  double min_scale = 0.9;
  double max_scale = 1.1;
  double max_fre_mm = 1.5;
  // Two points of one frame closer than this are the same point picked twice.
  double min_separation_mm = 1.0;
  // The points must spread at least this far (RMS) from their best-fit line, or the rotation
  // about that line is not determined by the data.
  double min_spread_from_line_mm = 2.0;
};

struct Registration {
  TransformKind kind = TransformKind::kSimilarity;
  // p_robot = scale * rotation * p_image + translation_mm
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  double scale = 1.0;
  Eigen::Vector3d translation_mm = Eigen::Vector3d::Zero();
  double fre_mm = 0.0;               // RMS over the pairs, in robot mm
  std::vector<double> residuals_mm;  // |T(image_i) - robot_i| per pair
  std::vector<Eigen::Vector3d> image_mm;
  std::vector<Eigen::Vector3d> robot_mm;

  Eigen::Vector3d toRobot(const Eigen::Vector3d& image_mm_point) const;
  Eigen::Vector3d toImage(const Eigen::Vector3d& robot_mm_point) const;
  Eigen::Matrix4d imageToRobot() const;  // homogeneous, scale included
};

// Checks the pairs, fits the transform and checks the fit. Errors are kInvalidArgument
// (counts, non-finite values) or kDegenerate (geometry, scale, FRE) with a reason token and a
// message that names the points and the limit, e.g.
//   "image points 1 and 3 are 0.40 mm apart (minimum 1.00 mm): the same point picked twice?"
Expected<Registration> registerPoints(const std::vector<Eigen::Vector3d>& image_mm,
                                      const std::vector<Eigen::Vector3d>& robot_mm,
                                      TransformKind kind, const RegistrationLimits& limits);

// A registration computed elsewhere (3D Slicer's, over OpenIGTLink): p_robot = matrix * p_image.
// The matrix must be a similarity (equal singular values within 1e-4, relative), proper (no
// mirror), with a bottom row 0 0 0 1 and a scale within the limits; reasons "non_finite",
// "not_affine", "not_similarity", "mirror", "scale_out_of_range", "out_of_range". The rotation is
// re-orthonormalised (the wire carries float32). No fiducials: FRE 0 and no points.
Expected<Registration> registrationFromMatrix(const Eigen::Matrix4d& image_to_robot,
                                              const RegistrationLimits& limits);

// The fiducial configuration as Fitzpatrick & West describe it: centroid, principal axes and,
// per axis k, f_k² = mean squared distance of the fiducials from that axis.
struct FiducialConfiguration {
  Eigen::Vector3d centroid_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();         // columns: principal axes
  Eigen::Vector3d axis_rms_sq_mm2 = Eigen::Vector3d::Zero();  // f_k²
  double sum_sq_mm2 = 0.0;                                    // Σ |p_i - centroid|²
  std::size_t count = 0;
};
FiducialConfiguration describeFiducials(const std::vector<Eigen::Vector3d>& points_mm);

// Expected RMS target registration error at `target_mm` (same frame as the fiducials) for an
// isotropic fiducial localisation error of RMS `fle_mm` (3-D), to first order:
//   rigid:      TRE² = FLE²/N · (1 + ⅓ Σ_k d_k²/f_k²)                    (Fitzpatrick–West)
//   similarity: TRE² = rigid + FLE²/3 · |r - c|² / Σ|p_i - c|²  (the scale estimate's variance;
//               scale is uncorrelated with rotation and translation about the centroid).
double expectedTre_mm(const FiducialConfiguration& fiducials, const Eigen::Vector3d& target_mm,
                      double fle_mm, TransformKind kind);

// Expected RMS FRE for that FLE: FLE · sqrt(1 - p/(3N)), p = 6 (rigid) or 7 (similarity);
// and the inverse, an FLE estimate from an observed FRE (noisy for N = 3).
double expectedFre_mm(std::size_t count, double fle_mm, TransformKind kind);
double estimatedFle_mm(std::size_t count, double fre_mm, TransformKind kind);

}  // namespace ignav::registration
