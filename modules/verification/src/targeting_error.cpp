#include "ignav/verification/targeting_error.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <Eigen/LU>

namespace ignav::verification {
namespace {

Status checkTransform(const Eigen::Matrix4d& m) {
  auto bad = [](const std::string& why) {
    return makeError(ErrorCode::kInvalidArgument, "image_to_robot: " + why, "bad_transform");
  };
  if (!m.allFinite()) return bad("not finite");
  if (m.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) return bad("bottom row is not 0 0 0 1");
  const double det = m.topLeftCorner<3, 3>().determinant();
  if (!(std::abs(det) > 1e-9)) return bad(fmt::format("singular (determinant {:g})", det));
  return Ok{};
}

Eigen::Vector3d apply(const Eigen::Matrix4d& m, const Eigen::Vector3d& p) {
  return m.topLeftCorner<3, 3>() * p + m.topRightCorner<3, 1>();
}

}  // namespace

Stats summarize(const std::vector<double>& values) {
  Stats s;
  s.count = values.size();
  if (values.empty()) return s;
  const auto n = static_cast<double>(values.size());
  double sum = 0.0, sum_sq = 0.0;
  s.min = s.max = values.front();
  for (double v : values) {
    sum += v;
    sum_sq += v * v;
    s.min = std::min(s.min, v);
    s.max = std::max(s.max, v);
  }
  s.mean = sum / n;
  s.rms = std::sqrt(sum_sq / n);
  if (values.size() >= 2) {
    double dev = 0.0;  // two passes: no cancellation
    for (double v : values)
      dev += (v - s.mean) * (v - s.mean);
    s.sd_sample = std::sqrt(dev / (n - 1.0));
  }
  return s;
}

Expected<TargetError> targetError(const PlannedTarget& target, const Eigen::Vector3d& actual_lps_mm,
                                  const Eigen::Matrix4d& image_to_robot) {
  if (auto ok = checkTransform(image_to_robot); !ok) return ok.error();
  if (!target.robot_mm.allFinite() || !actual_lps_mm.allFinite()) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("target {}: planned or actual position not finite", target.id),
                     "non_finite");
  }
  const Eigen::Matrix4d robot_to_image = image_to_robot.inverse();
  TargetError e;
  e.target_id = target.id;
  e.planned_robot_mm = target.robot_mm;
  e.actual_lps_mm = actual_lps_mm;
  e.planned_lps_mm = apply(robot_to_image, target.robot_mm);
  e.actual_robot_mm = apply(image_to_robot, actual_lps_mm);
  e.error_robot_mm = e.actual_robot_mm - e.planned_robot_mm;
  e.error_lps_mm = e.actual_lps_mm - e.planned_lps_mm;
  e.error_mm = e.error_robot_mm.norm();
  const Eigen::Vector2d across = e.error_robot_mm.head<2>();
  e.lateral_mm = across.norm();
  const Eigen::Vector2d planned_xy = target.robot_mm.head<2>();
  const Eigen::Vector2d radial =
      planned_xy.norm() > 1e-9 ? Eigen::Vector2d(planned_xy.normalized()) : Eigen::Vector2d(0, 1);
  const Eigen::Vector2d tangential(-radial.y(), radial.x());
  e.radial_mm = across.dot(radial);
  e.tangential_mm = across.dot(tangential);
  e.depth_mm = -e.error_robot_mm.z();
  return e;
}

ErrorSummary summarizeErrors(const std::vector<TargetError>& errors) {
  auto over = [&](auto&& f) {
    std::vector<double> v;
    v.reserve(errors.size());
    for (const auto& e : errors)
      v.push_back(f(e));
    return summarize(v);
  };
  ErrorSummary s;
  s.error = over([](const TargetError& e) { return e.error_mm; });
  s.lateral = over([](const TargetError& e) { return e.lateral_mm; });
  s.depth = over([](const TargetError& e) { return e.depth_mm; });
  s.abs_depth = over([](const TargetError& e) { return std::abs(e.depth_mm); });
  for (Eigen::Index a = 0; a < 3; ++a) {
    s.abs_axis_robot[static_cast<std::size_t>(a)] =
        over([a](const TargetError& e) { return std::abs(e.error_robot_mm[a]); });
    s.abs_axis_lps[static_cast<std::size_t>(a)] =
        over([a](const TargetError& e) { return std::abs(e.error_lps_mm[a]); });
  }
  return s;
}

Expected<Verification> verifyTargeting(const std::vector<PlannedTarget>& targets,
                                       const std::vector<Eigen::Vector3d>& seeds_lps_mm,
                                       const Eigen::Matrix4d& image_to_robot,
                                       const MatchOptions& options) {
  if (auto ok = checkTransform(image_to_robot); !ok) return ok.error();
  const Eigen::Matrix4d robot_to_image = image_to_robot.inverse();
  std::vector<TargetPoint> in_lps;
  in_lps.reserve(targets.size());
  for (const auto& t : targets) {
    if (!t.robot_mm.allFinite()) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("target {}: planned position not finite", t.id), "non_finite");
    }
    in_lps.push_back({t.id, apply(robot_to_image, t.robot_mm)});
  }
  auto match = matchSeeds(in_lps, seeds_lps_mm, options);
  if (!match) return match.error();
  Verification v;
  v.match = std::move(match).value();
  for (std::size_t i = 0; i < targets.size(); ++i) {
    const auto& seed = v.match.targets[i].seed;
    if (!seed) continue;
    auto e = targetError(targets[i], seeds_lps_mm[*seed], image_to_robot);
    if (!e) return e.error();
    v.errors.push_back(*e);
  }
  v.summary = summarizeErrors(v.errors);
  const Stats& s = v.summary.error;
  v.text = fmt::format(
      "targeting error over {} of {} targets: mean {:.2f} ± {:.2f} mm (sample SD), max {:.2f}, "
      "min {:.2f}, RMS {:.2f} mm; lateral mean {:.2f} mm, depth bias {:+.2f} mm",
      s.count, targets.size(), s.mean, s.sd_sample, s.max, s.min, s.rms, v.summary.lateral.mean,
      v.summary.depth.mean);
  if (!v.match.missing_targets.empty() || !v.match.extra_seeds.empty()) {
    v.text += fmt::format("; {} target(s) without a seed, {} extra seed(s)",
                          v.match.missing_targets.size(), v.match.extra_seeds.size());
  }
  return v;
}

}  // namespace ignav::verification
