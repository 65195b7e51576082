// The deflected landing point and the compensated inverse (docs/COMPENSATION.md).
#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>

#include <fmt/format.h>

#include <Eigen/Dense>

#include "ignav/compensation/compensation.hpp"
#include "ignav/kinematics/plane.hpp"

namespace ignav::compensation {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
// Newton stops here: the integrator's own tolerance (1e-12) leaves no more to gain.
constexpr double kNewtonFloor_mm = 1e-10;
// Central-difference steps for the Jacobian (rad, mm, mm).
constexpr double kStepAngle_rad = 1e-6;
constexpr double kStepLength_mm = 1e-6;
constexpr double kMaxTurn_rad = 0.5;
constexpr double kMaxMove_mm = 10.0;

std::string joints(const kinematics::Joints& j) {
  return fmt::format("θc {:.3f}°, zc {:.3f} mm, zs {:.3f} mm", j.theta_c_rad * 180.0 / M_PI,
                     j.z_c_mm, j.z_s_mm);
}

std::string point(const Eigen::Vector3d& p) {
  return fmt::format("({:.2f}, {:.2f}, {:.2f}) mm", p.x(), p.y(), p.z());
}

using Plane = kinematics::ThetaPlane;

// The stylet as it leaves a cannula whose tip turned by heading_rad (−Z, i.e. (0, −1), goes to
// (sin h, −cos h)); unturned when it is carried by translation only.
Eigen::Vector2d carried(const Eigen::Vector2d& stylet, double heading_rad, StyletCarry carry) {
  return carry == StyletCarry::kRotated ? Plane::turned(stylet, heading_rad) : stylet;
}

}  // namespace

Expected<CannulaDrift> cannulaDrift(const DeflectionModel& model, double z_c_mm) {
  if (!std::isfinite(z_c_mm)) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("z_c_mm = {} must be finite", z_c_mm));
  }
  if (z_c_mm <= 0.0) return CannulaDrift{};  // not in tissue
  auto path = deflection::simulate(model.needle, model.tissue, z_c_mm, z_c_mm);
  if (!path) return path.error();
  const auto& end = path->back();
  // The model bends towards its −y for k < 0; that side is +y′, where the stylet curves.
  return CannulaDrift{-end.y_mm, z_c_mm - end.z_mm, -end.gamma_rad};
}

Expected<Landing> predictLanding(const kinematics::Kinematics& kinematics,
                                 const DeflectionModel& model, const kinematics::Joints& j) {
  if (!std::isfinite(j.theta_c_rad) || !std::isfinite(j.z_c_mm) || !std::isfinite(j.z_s_mm)) {
    return makeError(ErrorCode::kInvalidArgument, "joints must be finite: " + joints(j));
  }
  auto drift = cannulaDrift(model, j.z_c_mm);
  if (!drift) return drift.error();
  const auto pose = kinematics.forward(j);
  const Plane plane(j.theta_c_rad);
  const Eigen::Vector2d cannula = plane.in(pose.cannula_tip_mm);
  // The cannula tip: pushed aside towards +y′ and short of its nominal depth.
  const Eigen::Vector2d moved = cannula + Eigen::Vector2d(drift->lateral_mm, drift->shortfall_mm);
  // The stylet from the cannula tip (offset and arc included), turned about it.
  const Eigen::Vector2d landed =
      moved + carried(plane.in(pose.tip_mm) - cannula, drift->heading_rad, model.carry);
  Landing out;
  out.tip_mm = plane.out(landed);
  out.cannula_tip_mm = plane.out(moved);
  out.nominal_tip_mm = pose.tip_mm;
  out.drift = *drift;
  return out;
}

Expected<PredictedPath> predictPath(const kinematics::Kinematics& kinematics,
                                    const DeflectionModel& model, const kinematics::Joints& j,
                                    double step_mm, double above_mm) {
  if (!(step_mm >= 0.01 && step_mm <= 10.0) || !(above_mm >= 0.0 && above_mm <= 1000.0)) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("path: step_mm = {} must lie in [0.01, 10] and above_mm = {} "
                                 "in [0, 1000]",
                                 step_mm, above_mm));
  }
  auto landing = predictLanding(kinematics, model, j);  // checks the joints and the tissue
  if (!landing) return landing.error();
  const auto nominal = kinematics.centreline(j, step_mm);
  const Plane plane(j.theta_c_rad);
  // The drift at every inserted length: where the cannula's tip went, the body behind it lies
  // (the bicycle model's needle follows its tip), so the body point that entered the tissue when
  // s mm were in is displaced as the tip was then. Linear between the integrator's samples.
  std::vector<deflection::PathSample> drift;
  if (j.z_c_mm > 0.0) {
    auto path = deflection::simulate(model.needle, model.tissue, j.z_c_mm, step_mm);
    if (!path) return path.error();
    drift = std::move(*path);
  }
  auto displacement = [&](double s_mm) -> Eigen::Vector2d {
    if (drift.empty() || s_mm <= 0.0) return Eigen::Vector2d::Zero();
    auto next =
        std::lower_bound(drift.begin(), drift.end(), s_mm,
                         [](const deflection::PathSample& p, double s) { return p.s_mm < s; });
    if (next == drift.end()) next = std::prev(drift.end());
    const auto prev = next == drift.begin() ? next : std::prev(next);
    const double span = next->s_mm - prev->s_mm;
    const double t = span > 0.0 ? (s_mm - prev->s_mm) / span : 1.0;
    const double y = prev->y_mm + t * (next->y_mm - prev->y_mm);
    const double z = prev->z_mm + t * (next->z_mm - prev->z_mm);
    return {-y, s_mm - z};  // towards +y′, and short of the straight push (as cannulaDrift)
  };
  PredictedPath out;
  const double length_mm = nominal.cannula_arc_mm.back();
  for (std::size_t i = 0; i < nominal.cannula_mm.size(); ++i) {
    const double behind_tip_mm = length_mm - nominal.cannula_arc_mm[i];
    if (behind_tip_mm > std::max(j.z_c_mm, 0.0) + above_mm) continue;  // inside the robot
    out.cannula_mm.push_back(
        plane.out(plane.in(nominal.cannula_mm[i]) + displacement(j.z_c_mm - behind_tip_mm)));
  }
  out.cannula_mm.back() = landing->cannula_tip_mm;  // the same point, exactly
  // The stylet keeps its shape relative to the cannula tip and turns with it (predictLanding).
  const Eigen::Vector2d moved = plane.in(landing->cannula_tip_mm);
  const Eigen::Vector2d cannula_tip = plane.in(nominal.cannula_mm.back());
  for (const auto& p : nominal.stylet_mm) {
    out.stylet_mm.push_back(plane.out(
        moved + carried(plane.in(p)-cannula_tip, landing->drift.heading_rad, model.carry)));
  }
  out.stylet_mm.back() = landing->tip_mm;
  return out;
}

Expected<Compensation> compensate(const kinematics::Kinematics& kinematics,
                                  const DeflectionModel& model, const Eigen::Vector3d& target_mm,
                                  const CompensationOptions& options) {
  if (!(options.tolerance_mm > 0.0) || options.max_iterations < 1) {
    return makeError(ErrorCode::kInvalidArgument,
                     "the tolerance must be positive and at least one iteration allowed");
  }
  if (auto ok = deflection::checkAdmissible(model.needle, model.tissue); !ok.admissible) {
    return makeError(ErrorCode::kInvalidArgument, "tissue: " + ok.reason, "inadmissible");
  }
  auto nominal = kinematics.inverse(target_mm);
  if (!nominal) return nominal.error();
  Compensation out;
  out.nominal = *nominal;
  out.nominal_landing_mm = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  const double radius = std::hypot(target_mm.x(), target_mm.y());
  const bool radius_ok = radius >= kinematics.minRadius_mm() && radius <= kinematics.maxRadius_mm();
  // The start: the exact joints, or, when the radius is out of range, those at the nearest radius
  // (the drift pushes the tip outwards, so a target a little beyond r_max may still be reached).
  kinematics::Joints q = out.nominal.joints;
  if (radius_ok) {
    auto landing = predictLanding(kinematics, model, q);
    if (!landing) return landing.error();
    out.nominal_landing_mm = landing->tip_mm;
  } else {
    q.theta_c_rad = radius > 0.0 ? std::atan2(-target_mm.x(), target_mm.y()) : 0.0;
    q.z_s_mm = kinematics.styletForRadius_mm(
        std::clamp(radius, kinematics.minRadius_mm(), kinematics.maxRadius_mm()));
    q.z_c_mm = kinematics.tipDepthAtHome_mm(q.z_s_mm) - target_mm.z();
  }

  auto miss = [&](const kinematics::Joints& j) -> Expected<Eigen::Vector3d> {
    auto landing = predictLanding(kinematics, model, j);
    if (!landing) return landing.error();
    return Eigen::Vector3d(landing->tip_mm - target_mm);
  };
  auto shifted = [](kinematics::Joints j, int axis, double by) {
    (axis == 0 ? j.theta_c_rad : axis == 1 ? j.z_c_mm : j.z_s_mm) += by;
    return j;
  };
  auto f = miss(q);
  if (!f) return f.error();
  Eigen::Vector3d residual = *f;
  int iterations = 0;
  while (iterations < options.max_iterations && residual.norm() > kNewtonFloor_mm) {
    Eigen::Matrix3d jacobian;
    for (int axis = 0; axis < 3; ++axis) {
      const double h = axis == 0 ? kStepAngle_rad : kStepLength_mm;
      auto plus = miss(shifted(q, axis, h));
      auto minus = miss(shifted(q, axis, -h));
      if (!plus || !minus) return plus ? minus.error() : plus.error();
      jacobian.col(axis) = (*plus - *minus) / (2.0 * h);
    }
    Eigen::Vector3d step = -jacobian.fullPivLu().solve(residual);
    if (!step.allFinite()) break;
    // A trust region: no step turns more than 0.5 rad or moves a joint more than 10 mm.
    step *= std::min(
        1.0, 1.0 / std::max({std::abs(step[0]) / kMaxTurn_rad, std::abs(step[1]) / kMaxMove_mm,
                             std::abs(step[2]) / kMaxMove_mm}));
    // Halve the step until the miss shrinks; none that does means the iteration has stalled.
    bool improved = false;
    for (double scale = 1.0; scale > 1e-6 && !improved; scale *= 0.5) {
      kinematics::Joints next{q.theta_c_rad + scale * step[0], q.z_c_mm + scale * step[1],
                              q.z_s_mm + scale * step[2]};
      auto r = miss(next);
      if (r && r->norm() < residual.norm()) {
        q = next;
        residual = *r;
        improved = true;
      }
    }
    ++iterations;
    if (!improved) break;
  }
  q.theta_c_rad = std::fmod(q.theta_c_rad, kTwoPi);
  if (q.theta_c_rad < 0.0) q.theta_c_rad += kTwoPi;
  out.compensated = q;
  out.compensated_landing_mm = residual + target_mm;
  out.residual_mm = residual.norm();
  out.iterations = iterations;
  const std::string nominal_text =
      joints(out.nominal.joints) + (out.nominal.reachable() ? ", reachable" : ", not reachable");
  const auto in_range = kinematics.checkJoints(q);
  if (!in_range) {
    // Converged outside the joint ranges, or stalled there: typically an aim inside the minimum
    // radius, where the tip radius r(z_s) bottoms out at z_s < 0 and no joints reach it at all.
    const std::string where = out.residual_mm <= options.tolerance_mm
                                  ? "compensated " + joints(q)
                                  : fmt::format("the iteration stops at {}, still {:.3g} mm off",
                                                joints(q), out.residual_mm);
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("target {}: the compensated pose is out of reach: {} ({}; "
                                 "nominal {})",
                                 point(target_mm), in_range.error().message, where, nominal_text),
                     "compensated_out_of_reach");
  }
  if (!(out.residual_mm <= options.tolerance_mm)) {
    return makeError(
        ErrorCode::kDegenerate,
        fmt::format("compensation for target {} did not converge: the predicted tip "
                    "still misses it by {:.3g} mm after {} Newton steps (at {}; "
                    "nominal {})",
                    point(target_mm), out.residual_mm, iterations, joints(q), nominal_text),
        "not_converged");
  }
  return out;
}

}  // namespace ignav::compensation
