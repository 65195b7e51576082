// Inverse kinematics: the paper's closed form (MODEL.md §6.2) and its exact refinement (§6.1).
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>

#include "ignav/kinematics/solver.hpp"

namespace ignav::kinematics {
namespace {

constexpr double kTwoPi = 6.28318530717958647692;
// Targets this close outside a limit are treated as on it: FK of a joint at its limit must
// invert to that limit despite rounding.
constexpr double kLimitSlack_mm = 1e-9;

double rotationFor(const Eigen::Vector3d& p) {
  // θc = atan2(-x, y) mod 2π; on the axis any rotation reaches the point, take 0.
  if (p.x() == 0.0 && p.y() == 0.0) return 0.0;
  double theta = std::atan2(-p.x(), p.y());
  if (theta < 0.0) theta += kTwoPi;
  if (theta >= kTwoPi) theta -= kTwoPi;
  return theta;
}

}  // namespace

const char* toString(Reach reach) {
  switch (reach) {
    case Reach::kReachable:
      return "reachable";
    case Reach::kInsideMinRadius:
      return "inside_min_radius";
    case Reach::kBeyondMaxRadius:
      return "beyond_max_radius";
    case Reach::kTooShallow:
      return "too_shallow";
    case Reach::kTooDeep:
      return "too_deep";
  }
  return "reachable";
}

double Kinematics::closedFormStylet_mm(double radius_mm) const {
  const double R = instrument_.stylet_radius_mm;
  const double phi = phi_rad_;
  if (rigid_) {
    // θd = 0: cos γ ≈ 1 - γ²/2 and cos ϕ ≈ 1 - ϕ²/2 in eq (10) give γ² = ϕ² + 2y/R.
    const double gamma = std::sqrt(std::max(0.0, phi * phi + 2.0 * radius_mm / R));
    return R * (gamma - phi);
  }
  // Eq (16), "+" branch (the denominator a/R - n² is negative).
  const double m = cf_m_, n = cf_n_;
  const double b = m * n - phi;
  const double disc = b * b - cf_den_ * (phi * phi - m * m + 2.0 * radius_mm / R);
  const double theta_d = (b + std::sqrt(std::max(0.0, disc))) / cf_den_;
  return instrument_.stylet_curved_length_mm - instrument_.cannula_deflected_radius_mm * theta_d;
}

double Kinematics::styletForRadius_mm(double radius_mm) const {
  const double zs_max = instrument_.stylet_travel_mm;
  if (radius_mm <= r_min_mm_) return 0.0;
  if (radius_mm >= r_max_mm_) return zs_max;
  // r(zs) is strictly increasing (checked in create), so [lo, hi] always brackets the root.
  // Halley's iteration (cubic convergence) from the closed form takes 2-3 evaluations; a step
  // leaving the bracket bisects instead.
  double lo = 0.0, hi = zs_max;
  double zs = std::clamp(closedFormStylet_mm(radius_mm), lo, hi);
  for (int i = 0; i < 60; ++i) {
    const RadialProfile p = radialProfile(zs);
    const double f = p.radius_mm - radius_mm;
    if (f == 0.0) return zs;
    if (f < 0.0) {
      lo = zs;
    } else {
      hi = zs;
    }
    double next = zs - 2.0 * f * p.slope / (2.0 * p.slope * p.slope - f * p.curvature);
    const bool halley = next > lo && next < hi;
    if (!halley) next = 0.5 * (lo + hi);
    const double step = std::abs(next - zs);
    zs = next;
    // Halley's error after a step δ is of order δ³ (times derivative ratios ≲ 1/mm²): far
    // below 1e-12 mm once δ < 1e-5 mm, so stop without another evaluation. A bisection step
    // gives no such guarantee.
    if ((halley && step < 1e-5) || step <= 1e-13 * (1.0 + zs) || hi - lo <= 1e-15 * zs_max) {
      break;
    }
  }
  return zs;
}

Expected<InverseSolution> Kinematics::inverse(const Eigen::Vector3d& p) const {
  if (!p.allFinite()) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "target (%g, %g, %g) mm has a non-finite coordinate", p.x(),
                  p.y(), p.z());
    return makeError(ErrorCode::kInvalidArgument, buf);
  }
  InverseSolution s;
  const double r = std::hypot(p.x(), p.y());
  const double zc_max = instrument_.cannula_travel_mm;
  if (r < r_min_mm_ - kLimitSlack_mm || r > r_max_mm_ + kLimitSlack_mm) {
    const bool inside = r < r_min_mm_;
    s.reach = inside ? Reach::kInsideMinRadius : Reach::kBeyondMaxRadius;
    s.excess_mm = inside ? r_min_mm_ - r : r - r_max_mm_;
    // Out of reach sideways; if it is further out of reach in depth (a point metres above the
    // robot is not "inside the minimum radius"), that is the reason a person needs.
    const double zc = tipDepthAtHome_mm(inside ? 0.0 : instrument_.stylet_travel_mm) - p.z();
    if (-zc > s.excess_mm) {
      s.reach = Reach::kTooShallow;
      s.excess_mm = -zc;
    } else if (zc - zc_max > s.excess_mm) {
      s.reach = Reach::kTooDeep;
      s.excess_mm = zc - zc_max;
    }
    return s;
  }
  s.joints.theta_c_rad = rotationFor(p);
  s.joints.z_s_mm = styletForRadius_mm(r);
  double zc = tipDepthAtHome_mm(s.joints.z_s_mm) - p.z();
  if (zc < -kLimitSlack_mm) {
    s.reach = Reach::kTooShallow;
    s.excess_mm = -zc;
  } else if (zc > zc_max + kLimitSlack_mm) {
    s.reach = Reach::kTooDeep;
    s.excess_mm = zc - zc_max;
  } else {
    zc = std::clamp(zc, 0.0, zc_max);
  }
  s.joints.z_c_mm = zc;
  return s;
}

Joints Kinematics::closedFormJoints(const Eigen::Vector3d& p) const {
  Joints j;
  j.theta_c_rad = rotationFor(p);
  j.z_s_mm = closedFormStylet_mm(std::hypot(p.x(), p.y()));
  // Corrected eq (17): zc = z0(zs) - z with the model of (7)-(8), i.e. without the exit offset.
  j.z_c_mm = planar(j.z_s_mm, ExitOffset::kNone).z_mm - p.z();
  return j;
}

ClosedFormSolution Kinematics::inverseClosedForm(const Eigen::Vector3d& p) const {
  ClosedFormSolution s;
  s.joints = closedFormJoints(p);
  s.clipped_joints = s.joints;
  s.clipped_joints.z_s_mm = std::clamp(s.joints.z_s_mm, 0.0, instrument_.stylet_travel_mm);
  s.clipped_joints.z_c_mm = std::clamp(s.joints.z_c_mm, 0.0, instrument_.cannula_travel_mm);
  s.clipped =
      s.clipped_joints.z_s_mm != s.joints.z_s_mm || s.clipped_joints.z_c_mm != s.joints.z_c_mm;
  s.error_mm = (forward(s.clipped_joints).tip_mm - p).norm();
  return s;
}

namespace {

// printf into a string as long as it takes: a target 1e300 mm away prints 300 digits, and the
// fixed buffer this replaced was overrun (found by fuzz_command, docs/RELIABILITY.md).
__attribute__((format(printf, 1, 2))) std::string printed(const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list count;
  va_copy(count, args);
  const int n = std::vsnprintf(nullptr, 0, format, count);
  va_end(count);
  std::string out(static_cast<std::size_t>(std::max(0, n)), '\0');
  if (n > 0) std::vsnprintf(out.data(), out.size() + 1, format, args);
  va_end(args);
  return out;
}

}  // namespace

std::string Kinematics::describe(const InverseSolution& s, const Eigen::Vector3d& p) const {
  const std::string target = printed("target (%.3f, %.3f, %.3f) mm ", p.x(), p.y(), p.z());
  switch (s.reach) {
    case Reach::kReachable:
      return target + "is reachable";
    case Reach::kInsideMinRadius:
      return target +
             printed("is %.3f mm inside the minimum radius %.3f mm around the cannula axis",
                     s.excess_mm, r_min_mm_);
    case Reach::kBeyondMaxRadius:
      return target +
             printed("is %.3f mm beyond the maximum radius %.3f mm", s.excess_mm, r_max_mm_);
    case Reach::kTooShallow:
      return target + printed("is %.3f mm too shallow: it needs cannula translation %.3f mm < 0",
                              s.excess_mm, s.joints.z_c_mm);
    case Reach::kTooDeep:
      return target +
             printed("is %.3f mm too deep: it needs cannula translation %.3f mm > travel %.3f mm",
                     s.excess_mm, s.joints.z_c_mm, instrument_.cannula_travel_mm);
  }
  return target;
}

}  // namespace ignav::kinematics
