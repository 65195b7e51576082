#include "ignav/registration/point_registration.hpp"

#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <fmt/format.h>

namespace ignav::registration {
namespace {

using Points = std::vector<Eigen::Vector3d>;

Error reject(ErrorCode code, const char* reason, std::string message) {
  return makeError(code, std::move(message), reason);
}

std::string formatPoint(const Eigen::Vector3d& p) {
  return fmt::format("({:g}, {:g}, {:g})", p.x(), p.y(), p.z());
}

// Finite, and within a range where squared distances cannot overflow: no scanner or robot
// frame spans a kilometre.
constexpr double kMaxCoordinate_mm = 1e6;

Status checkFinite(const Points& points, const char* frame) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      return reject(ErrorCode::kInvalidArgument, "non_finite",
                    fmt::format("{} point {} {} has a non-finite coordinate", frame, i + 1,
                                formatPoint(points[i])));
    }
    if (points[i].cwiseAbs().maxCoeff() > kMaxCoordinate_mm) {
      return reject(ErrorCode::kInvalidArgument, "out_of_range",
                    fmt::format("{} point {} {} lies beyond {:g} mm from the origin", frame, i + 1,
                                formatPoint(points[i]), kMaxCoordinate_mm));
    }
  }
  return Ok{};
}

Status checkSeparation(const Points& points, const char* frame, double min_separation_mm) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    for (std::size_t j = i + 1; j < points.size(); ++j) {
      const double d = (points[i] - points[j]).norm();
      if (d < min_separation_mm) {
        return reject(
            ErrorCode::kDegenerate, "coincident",
            fmt::format("{} points {} and {} are {:.2f} mm apart (minimum {:.2f} mm): the "
                        "same point picked twice?",
                        frame, i + 1, j + 1, d, min_separation_mm));
      }
    }
  }
  return Ok{};
}

// Collinear, or so nearly that the rotation about the common line rests on noise: the RMS
// distance from the best-fit line (the smaller two principal directions) is too small.
Status checkSpread(const Points& points, const char* frame, double min_spread_mm) {
  Eigen::Matrix3Xd centred(3, points.size());
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points)
    centroid += p;
  centroid /= static_cast<double>(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    centred.col(i) = points[i] - centroid;
  const Eigen::Vector3d sigma = Eigen::JacobiSVD<Eigen::Matrix3Xd>(centred).singularValues();
  const double off_line_mm =
      std::sqrt((sigma(1) * sigma(1) + sigma(2) * sigma(2)) / static_cast<double>(points.size()));
  const bool exactly = sigma(0) <= 1e-9 || sigma(1) <= 1e-6 * sigma(0);
  if (exactly || off_line_mm < min_spread_mm) {
    return reject(ErrorCode::kDegenerate, "collinear",
                  fmt::format("the {} {} points lie within {:.2f} mm (RMS) of one line; they must "
                              "spread at least {:.2f} mm off it, or the rotation about that line "
                              "is undetermined",
                              points.size(), frame, off_line_mm, min_spread_mm));
  }
  return Ok{};
}

}  // namespace

const char* toString(TransformKind kind) {
  return kind == TransformKind::kRigid ? "rigid" : "similarity";
}

Eigen::Vector3d Registration::toRobot(const Eigen::Vector3d& image_mm_point) const {
  return scale * (rotation * image_mm_point) + translation_mm;
}

Eigen::Vector3d Registration::toImage(const Eigen::Vector3d& robot_mm_point) const {
  return rotation.transpose() * (robot_mm_point - translation_mm) / scale;
}

Eigen::Matrix4d Registration::imageToRobot() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = scale * rotation;
  m.topRightCorner<3, 1>() = translation_mm;
  return m;
}

Expected<Registration> registrationFromMatrix(const Eigen::Matrix4d& m,
                                              const RegistrationLimits& limits) {
  auto reject = [](const char* reason, std::string message) -> Expected<Registration> {
    return makeError(ErrorCode::kDegenerate, "image-to-robot matrix: " + std::move(message),
                     reason);
  };
  if (!m.allFinite()) return reject("non_finite", "an element is not finite");
  const Eigen::RowVector4d bottom = m.row(3);
  if ((bottom - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6) {
    return reject("not_affine", fmt::format("the bottom row is [{:.4g} {:.4g} {:.4g} {:.4g}], "
                                            "not [0 0 0 1]",
                                            bottom(0), bottom(1), bottom(2), bottom(3)));
  }
  const Eigen::Matrix3d a = m.topLeftCorner<3, 3>();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv(2) > 0.0) || (sv(0) - sv(2)) / sv(0) > 1e-4) {
    return reject("not_similarity",
                  fmt::format("its 3x3 part stretches unevenly (singular values {:.6g}, {:.6g}, "
                              "{:.6g}): shear or anisotropic scale is not a registration",
                              sv(0), sv(1), sv(2)));
  }
  if (a.determinant() < 0.0) {
    return reject("mirror", "it mirrors (negative determinant): RAS and LPS mixed up?");
  }
  const Eigen::Vector3d t = m.topRightCorner<3, 1>();
  if (t.cwiseAbs().maxCoeff() > 1e6) {
    return reject("out_of_range",
                  fmt::format("a translation of {:.4g} mm", t.cwiseAbs().maxCoeff()));
  }
  Registration r;
  r.scale = sv.mean();
  r.kind = std::abs(r.scale - 1.0) < 1e-6 ? TransformKind::kRigid : TransformKind::kSimilarity;
  r.rotation = svd.matrixU() * svd.matrixV().transpose();
  r.translation_mm = t;
  if (!(r.scale >= limits.min_scale && r.scale <= limits.max_scale)) {
    return reject("scale_out_of_range",
                  fmt::format("scale {:.4f} is outside the plausible range [{:.4f}, {:.4f}]",
                              r.scale, limits.min_scale, limits.max_scale));
  }
  return r;
}

Expected<Registration> registerPoints(const Points& image_mm, const Points& robot_mm,
                                      TransformKind kind, const RegistrationLimits& limits) {
  if (image_mm.size() != robot_mm.size()) {
    return reject(ErrorCode::kInvalidArgument, "count_mismatch",
                  fmt::format("{} image points but {} robot points: they must pair up",
                              image_mm.size(), robot_mm.size()));
  }
  if (image_mm.size() < 3) {
    return reject(
        ErrorCode::kInvalidArgument, "too_few_pairs",
        fmt::format("{} point pairs given; a registration needs at least 3", image_mm.size()));
  }
  for (const auto& [points, frame] : {std::pair{&image_mm, "image"}, {&robot_mm, "robot"}}) {
    if (auto s = checkFinite(*points, frame); !s) return s.error();
  }
  for (const auto& [points, frame] : {std::pair{&image_mm, "image"}, {&robot_mm, "robot"}}) {
    if (auto s = checkSeparation(*points, frame, limits.min_separation_mm); !s) return s.error();
    if (auto s = checkSpread(*points, frame, limits.min_spread_from_line_mm); !s) {
      return s.error();
    }
  }

  Eigen::Matrix3Xd src(3, image_mm.size());
  Eigen::Matrix3Xd dst(3, robot_mm.size());
  for (std::size_t i = 0; i < image_mm.size(); ++i) {
    src.col(i) = image_mm[i];
    dst.col(i) = robot_mm[i];
  }
  const Eigen::Matrix4d m = Eigen::umeyama(src, dst, kind == TransformKind::kSimilarity);

  Registration r;
  r.kind = kind;
  r.scale = m.topLeftCorner<3, 3>().col(0).norm();
  r.rotation = m.topLeftCorner<3, 3>() / r.scale;
  r.translation_mm = m.topRightCorner<3, 1>();
  r.image_mm = image_mm;
  r.robot_mm = robot_mm;
  if (!(r.scale >= limits.min_scale && r.scale <= limits.max_scale)) {
    return reject(
        ErrorCode::kDegenerate, "scale_out_of_range",
        fmt::format("the fitted scale {:.4f} is outside the plausible range [{:.4f}, {:.4f}]: "
                    "are the points paired in the right order?",
                    r.scale, limits.min_scale, limits.max_scale));
  }
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < image_mm.size(); ++i) {
    const double e = (r.toRobot(image_mm[i]) - robot_mm[i]).norm();
    r.residuals_mm.push_back(e);
    sum_sq += e * e;
  }
  r.fre_mm = std::sqrt(sum_sq / static_cast<double>(image_mm.size()));
  if (r.fre_mm > limits.max_fre_mm) {
    std::size_t worst = 0;
    for (std::size_t i = 1; i < r.residuals_mm.size(); ++i) {
      if (r.residuals_mm[i] > r.residuals_mm[worst]) worst = i;
    }
    return reject(
        ErrorCode::kDegenerate, "fre_too_large",
        fmt::format("FRE {:.2f} mm exceeds the limit {:.2f} mm (worst: pair {}, {:.2f} mm): "
                    "re-pick the points or check their order",
                    r.fre_mm, limits.max_fre_mm, worst + 1, r.residuals_mm[worst]));
  }
  return r;
}

FiducialConfiguration describeFiducials(const Points& points_mm) {
  FiducialConfiguration f;
  f.count = points_mm.size();
  if (points_mm.empty()) return f;
  for (const auto& p : points_mm)
    f.centroid_mm += p;
  f.centroid_mm /= static_cast<double>(points_mm.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const auto& p : points_mm) {
    const Eigen::Vector3d d = p - f.centroid_mm;
    covariance += d * d.transpose();
    f.sum_sq_mm2 += d.squaredNorm();
  }
  covariance /= static_cast<double>(points_mm.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(covariance);
  f.axes = eig.eigenvectors();
  const Eigen::Vector3d lambda = eig.eigenvalues().cwiseMax(0.0);
  // Mean squared distance from axis k = the variance along the other two axes.
  f.axis_rms_sq_mm2 = Eigen::Vector3d::Constant(lambda.sum()) - lambda;
  return f;
}

double expectedTre_mm(const FiducialConfiguration& fiducials, const Eigen::Vector3d& target_mm,
                      double fle_mm, TransformKind kind) {
  if (fiducials.count == 0) return std::numeric_limits<double>::infinity();
  const double n = static_cast<double>(fiducials.count);
  const Eigen::Vector3d r = target_mm - fiducials.centroid_mm;
  double ratio_sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    if (fiducials.axis_rms_sq_mm2(k) <= 0.0) return std::numeric_limits<double>::infinity();
    const double along = r.dot(fiducials.axes.col(k));
    const double d_sq = r.squaredNorm() - along * along;
    ratio_sum += d_sq / fiducials.axis_rms_sq_mm2(k);
  }
  const double fle_sq = fle_mm * fle_mm;
  double tre_sq = fle_sq / n * (1.0 + ratio_sum / 3.0);
  if (kind == TransformKind::kSimilarity) {
    tre_sq += fle_sq / 3.0 * r.squaredNorm() / fiducials.sum_sq_mm2;
  }
  return std::sqrt(tre_sq);
}

namespace {
double freFactor(std::size_t count, TransformKind kind) {
  const double parameters = kind == TransformKind::kRigid ? 6.0 : 7.0;
  const double dof = 3.0 * static_cast<double>(count);
  return dof > parameters ? std::sqrt(1.0 - parameters / dof) : 0.0;
}
}  // namespace

double expectedFre_mm(std::size_t count, double fle_mm, TransformKind kind) {
  return fle_mm * freFactor(count, kind);
}

double estimatedFle_mm(std::size_t count, double fre_mm, TransformKind kind) {
  const double f = freFactor(count, kind);
  return f > 0.0 ? fre_mm / f : std::numeric_limits<double>::infinity();
}

}  // namespace ignav::registration
