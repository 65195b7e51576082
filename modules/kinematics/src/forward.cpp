// Forward kinematics and geometry validation (MODEL.md §3-4).
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "ignav/kinematics/solver.hpp"

namespace ignav::kinematics {
namespace {

constexpr double kPi = 3.14159265358979323846;

Error configError(const std::string& key, const std::string& what) {
  return makeError(ErrorCode::kConfig, key + ": " + what);
}

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

const char* toString(ExitOffset offset) {
  switch (offset) {
    case ExitOffset::kLateral:
      return "lateral";
    case ExitOffset::kAxial:
      return "axial";
    case ExitOffset::kNone:
      return "none";
  }
  return "lateral";
}

Kinematics::Kinematics(const Instrument& instrument) : instrument_(instrument) {
  const Instrument& g = instrument_;
  rigid_ = std::isinf(g.cannula_deflected_radius_mm);
  inv_rd_ = rigid_ ? 0.0 : 1.0 / g.cannula_deflected_radius_mm;
  clearance_mm_ = 0.5 * (g.cannula_inner_diameter_mm - g.stylet_outer_diameter_mm);
  // Across the diametral clearance the stylet arc turns by ϕ: R(1 - cos ϕ) = dc - ds (eq 5).
  phi_rad_ = std::acos(1.0 - 2.0 * clearance_mm_ / g.stylet_radius_mm);
  cos_phi_ = std::cos(phi_rad_);
  sin_phi_ = std::sin(phi_rad_);
  const double R = g.stylet_radius_mm;
  cf_m_ = phi_rad_ + g.stylet_curved_length_mm / R;
  if (!rigid_) {
    cf_n_ = 1.0 - g.cannula_deflected_radius_mm / R;
    cf_den_ = cf_n_ - cf_n_ * cf_n_;  // a/R - n² with a/R = n
  }
}

Expected<Kinematics> Kinematics::create(const Instrument& g) {
  struct Field {
    const char* key;
    double value;
  };
  const Field positive[] = {
      {"robot.stylet.radius_mm", g.stylet_radius_mm},
      {"robot.stylet.outer_diameter_mm", g.stylet_outer_diameter_mm},
      {"robot.stylet.travel_mm", g.stylet_travel_mm},
      {"robot.stylet.curved_length_mm", g.stylet_curved_length_mm},
      {"robot.cannula.inner_diameter_mm", g.cannula_inner_diameter_mm},
      {"robot.cannula.outer_diameter_mm", g.cannula_outer_diameter_mm},
      {"robot.cannula.travel_mm", g.cannula_travel_mm},
      {"robot.cannula.deflected_radius_mm", g.cannula_deflected_radius_mm},
  };
  for (const Field& f : positive) {
    if (std::isnan(f.value)) return configError(f.key, "is NaN; a number is required");
    if (!(f.value > 0.0)) return configError(f.key, "must be positive (got " + num(f.value) + ")");
  }
  for (const Field& f : positive) {
    // Only the deflected radius may be infinite (a rigid cannula).
    if (std::isinf(f.value) && std::string(f.key) != "robot.cannula.deflected_radius_mm") {
      return configError(f.key, "must be finite (got " + num(f.value) + ")");
    }
  }
  if (!std::isfinite(g.cannula_fixed_offset_mm) || g.cannula_fixed_offset_mm < 0.0) {
    return configError("robot.cannula.fixed_offset_mm",
                       "must be a finite length >= 0 (got " + num(g.cannula_fixed_offset_mm) + ")");
  }
  if (g.stylet_outer_diameter_mm > g.cannula_inner_diameter_mm) {
    return configError("robot.stylet.outer_diameter_mm",
                       "stylet (" + num(g.stylet_outer_diameter_mm) +
                           " mm) is wider than the cannula bore robot.cannula.inner_diameter_mm (" +
                           num(g.cannula_inner_diameter_mm) + " mm)");
  }
  if (g.cannula_outer_diameter_mm <= g.cannula_inner_diameter_mm) {
    return configError("robot.cannula.outer_diameter_mm",
                       "must exceed robot.cannula.inner_diameter_mm (" +
                           num(g.cannula_outer_diameter_mm) +
                           " <= " + num(g.cannula_inner_diameter_mm) + ")");
  }
  if (g.cannula_inner_diameter_mm - g.stylet_outer_diameter_mm >= g.stylet_radius_mm) {
    return configError("robot.stylet.radius_mm",
                       "the diametral clearance dc - ds must be below the stylet radius (exit "
                       "angle eq. 5 would exceed 90 degrees)");
  }
  if (g.stylet_travel_mm > g.stylet_curved_length_mm) {
    return configError("robot.stylet.travel_mm",
                       "stylet travel (" + num(g.stylet_travel_mm) +
                           " mm) exceeds robot.stylet.curved_length_mm (" +
                           num(g.stylet_curved_length_mm) +
                           " mm); the model covers only the precurved section");
  }
  if (g.cannula_deflected_radius_mm <= g.stylet_radius_mm) {
    return configError("robot.cannula.deflected_radius_mm",
                       "must exceed robot.stylet.radius_mm (" + num(g.stylet_radius_mm) +
                           " mm): the stylet bends the cannula less than itself (got " +
                           num(g.cannula_deflected_radius_mm) + ")");
  }
  Kinematics k(g);
  // The inverse is unique only while the tip radius grows with z_s (MODEL.md §5). True for any
  // sensible instrument; checked on a fine grid so a strange one is refused, not mis-solved.
  constexpr int kSamples = 2000;
  double previous_r = 0.0;
  for (int i = 0; i <= kSamples; ++i) {
    const double zs = g.stylet_travel_mm * i / kSamples;
    const RadialProfile profile = k.radialProfile(zs);
    const double r = profile.radius_mm, slope = profile.slope;
    // The slope may vanish at zs = 0 (no clearance: the tip starts on the axis) but the radius
    // must grow from sample to sample.
    const bool grows = i == 0 ? r >= 0.0 : r > previous_r;
    previous_r = r;
    if (!(slope >= 0.0) || !grows) {
      return configError("robot.stylet",
                         "the tip radius does not grow monotonically with stylet deployment "
                         "(dr/dzs = " +
                             num(slope) + " at zs = " + num(zs) +
                             " mm), so targets would have no unique joints; shorten "
                             "robot.stylet.travel_mm or increase robot.stylet.radius_mm");
    }
  }
  k.r_min_mm_ = k.planar(0.0, g.exit_offset).y_mm;
  k.r_max_mm_ = k.planar(g.stylet_travel_mm, g.exit_offset).y_mm;
  return k;
}

Kinematics::CannulaBend Kinematics::cannulaBend(double z_s_mm) const {
  const Instrument& g = instrument_;
  const double arc_mm = g.stylet_curved_length_mm - z_s_mm;  // deflected cannula arc, L0 - zs
  // Straight cannula part from P0 to the start of the deflected arc; the cannula length
  // zfixed + zsmax + zc is preserved whatever zs is (MODEL.md A2).
  const double straight_mm = g.cannula_fixed_offset_mm + g.stylet_travel_mm - arc_mm;
  if (rigid_) return {0.0, 0.0, 1.0, 0.0, -straight_mm - arc_mm};
  const double theta_d = arc_mm * inv_rd_;
  const double sin_d = std::sin(theta_d), cos_d = std::cos(theta_d);
  // Rd(1 - cos θd) (eq 3) as Rd sin²θd / (1 + cos θd): no cancellation for small θd and no third
  // trigonometric call in the IK's inner loop.
  return {theta_d, sin_d, cos_d, g.cannula_deflected_radius_mm * sin_d * sin_d / (1.0 + cos_d),
          -straight_mm - g.cannula_deflected_radius_mm * sin_d};  // eq (4)
}

Kinematics::Planar Kinematics::planar(double z_s_mm, ExitOffset offset) const {
  const double R = instrument_.stylet_radius_mm;
  const CannulaBend b = cannulaBend(z_s_mm);
  const double theta_d = b.theta_d_rad, sin_d = b.sin_d, cos_d = b.cos_d;
  const double y2 = b.tip_y_mm, z2 = b.tip_z_mm;
  double dy = 0.0, dz = 0.0;  // eq (9), MODEL.md A3
  switch (offset) {
    case ExitOffset::kLateral:
      dy = clearance_mm_ * cos_d;
      dz = clearance_mm_ * sin_d;
      break;
    case ExitOffset::kAxial:
      dy = clearance_mm_ * sin_d;
      dz = -clearance_mm_ * cos_d;
      break;
    case ExitOffset::kNone:
      break;
  }
  // ψ0 = θd + ϕ by angle addition, saving a sincos.
  const double sin_psi0 = sin_d * cos_phi_ + cos_d * sin_phi_;
  const double cos_psi0 = cos_d * cos_phi_ - sin_d * sin_phi_;
  const double gamma = theta_d + phi_rad_ + z_s_mm / R;
  Planar p;
  p.y_mm = y2 + dy + R * (cos_psi0 - std::cos(gamma));  // eq (7)
  p.z_mm = z2 + dz - R * (std::sin(gamma) - sin_psi0);  // eq (8), sign restored
  p.cannula_y_mm = y2;
  p.cannula_z_mm = z2;
  p.gamma_rad = gamma;
  return p;
}

Kinematics::RadialProfile Kinematics::radialProfile(double z_s_mm) const {
  const Instrument& g = instrument_;
  const double R = g.stylet_radius_mm;
  const CannulaBend b = cannulaBend(z_s_mm);
  const double theta_d = b.theta_d_rad, sin_d = b.sin_d, cos_d = b.cos_d, y2 = b.tip_y_mm;
  const double sin_psi0 = sin_d * cos_phi_ + cos_d * sin_phi_;
  const double cos_psi0 = cos_d * cos_phi_ - sin_d * sin_phi_;
  const double gamma = theta_d + phi_rad_ + z_s_mm / R;
  const double sin_g = std::sin(gamma), cos_g = std::cos(gamma);
  // The exit offset's term of r and its first two derivatives.
  const double c = clearance_mm_, k = inv_rd_;
  double dy = 0.0, d_dy = 0.0, dd_dy = 0.0;
  switch (g.exit_offset) {
    case ExitOffset::kLateral:
      dy = c * cos_d;
      d_dy = c * k * sin_d;
      dd_dy = -c * k * k * cos_d;
      break;
    case ExitOffset::kAxial:
      dy = c * sin_d;
      d_dy = -c * k * cos_d;
      dd_dy = -c * k * k * sin_d;
      break;
    case ExitOffset::kNone:
      break;
  }
  // d/dzs with dθd/dzs = dψ0/dzs = -1/Rd and dγ/dzs = 1/R - 1/Rd (MODEL.md §5).
  const double dgamma = 1.0 / R - k;
  RadialProfile out;
  out.radius_mm = y2 + dy + R * (cos_psi0 - cos_g);
  out.slope = -sin_d + R * k * sin_psi0 + R * dgamma * sin_g + d_dy;
  out.curvature = k * cos_d - R * k * k * cos_psi0 + R * dgamma * dgamma * cos_g + dd_dy;
  return out;
}

double Kinematics::tipDepthAtHome_mm(double z_s_mm) const {
  return planar(z_s_mm, instrument_.exit_offset).z_mm;
}

TipPose Kinematics::forward(const Joints& j) const {
  const Planar p = planar(j.z_s_mm, instrument_.exit_offset);
  const double s = std::sin(j.theta_c_rad), c = std::cos(j.theta_c_rad);
  // p = Rz(θc)·(0, y', z'), MODEL.md §2.
  TipPose pose;
  pose.tip_mm = {-p.y_mm * s, p.y_mm * c, p.z_mm - j.z_c_mm};
  pose.cannula_tip_mm = {-p.cannula_y_mm * s, p.cannula_y_mm * c, p.cannula_z_mm - j.z_c_mm};
  pose.approach_rad = p.gamma_rad;
  return pose;
}

Centreline Kinematics::centreline(const Joints& j, double step_mm) const {
  const Instrument& g = instrument_;
  const double R = g.stylet_radius_mm;
  const CannulaBend b = cannulaBend(j.z_s_mm);
  const Planar tip = planar(j.z_s_mm, g.exit_offset);
  const double arc_mm = rigid_ ? 0.0 : g.stylet_curved_length_mm - j.z_s_mm;
  const double length_mm = g.cannula_fixed_offset_mm + g.stylet_travel_mm + j.z_c_mm;
  const double straight_mm = length_mm - arc_mm;
  const double s = std::sin(j.theta_c_rad), c = std::cos(j.theta_c_rad);
  auto at = [&](double y, double z) { return Eigen::Vector3d(-y * s, y * c, z); };
  auto count = [&](double mm) { return std::max(1, static_cast<int>(std::ceil(mm / step_mm))); };
  Centreline out;
  // P0 is fixed to the casing: pushing the cannula in lengthens its straight part (MODEL.md §3).
  const int n_straight = count(straight_mm);
  for (int i = 0; i < n_straight; ++i) {
    const double a = straight_mm * i / n_straight;
    out.cannula_mm.push_back(at(0.0, -a));
    out.cannula_arc_mm.push_back(a);
  }
  const int n_arc = arc_mm > 0.0 ? count(arc_mm) : 0;
  for (int i = 0; i <= n_arc; ++i) {
    const double t = n_arc > 0 ? b.theta_d_rad * i / n_arc : 0.0;
    const double rd = g.cannula_deflected_radius_mm;
    out.cannula_mm.push_back(at(rd * (1.0 - std::cos(t)), -straight_mm - rd * std::sin(t)));
    out.cannula_arc_mm.push_back(straight_mm + (n_arc > 0 ? arc_mm * i / n_arc : 0.0));
  }
  out.cannula_mm.back() = at(tip.cannula_y_mm, tip.cannula_z_mm - j.z_c_mm);
  // The stylet leaves at P2 + Δ with heading ψ0 and turns to γ over z_s of arc (eqs 7, 8).
  const double psi0 = b.theta_d_rad + phi_rad_;
  const Eigen::Vector2d exit(tip.y_mm - R * (std::cos(psi0) - std::cos(tip.gamma_rad)),
                             tip.z_mm + R * (std::sin(tip.gamma_rad) - std::sin(psi0)));
  const int n_stylet = count(std::max(j.z_s_mm, step_mm));
  for (int i = 0; i <= n_stylet; ++i) {
    const double psi = psi0 + j.z_s_mm / R * i / n_stylet;
    out.stylet_mm.push_back(at(exit.x() + R * (std::cos(psi0) - std::cos(psi)),
                               exit.y() - R * (std::sin(psi) - std::sin(psi0)) - j.z_c_mm));
  }
  out.stylet_mm.back() = forward(j).tip_mm;
  return out;
}

Status Kinematics::checkJoints(const Joints& j) const {
  const Instrument& g = instrument_;
  auto out = [](const char* name, double v, double hi, const char* unit, const char* what) {
    std::ostringstream s;
    s << name << " = " << v << " is outside the " << what << " [0, " << hi << "] " << unit;
    return makeError(ErrorCode::kInvalidArgument, s.str());
  };
  if (!std::isfinite(j.theta_c_rad)) return out("theta_c", j.theta_c_rad, 360, "deg", "rotation");
  if (!std::isfinite(j.z_c_mm) || j.z_c_mm < 0.0 || j.z_c_mm > g.cannula_travel_mm) {
    return out("z_c_mm", j.z_c_mm, g.cannula_travel_mm, "mm", "cannula travel");
  }
  if (!std::isfinite(j.z_s_mm) || j.z_s_mm < 0.0 || j.z_s_mm > g.stylet_travel_mm) {
    return out("z_s_mm", j.z_s_mm, g.stylet_travel_mm, "mm", "stylet travel");
  }
  return Ok{};
}

WorkspaceFigures Kinematics::workspace() const {
  const Instrument& g = instrument_;
  const double R = g.stylet_radius_mm;
  const double zs = g.stylet_travel_mm, zc = g.cannula_travel_mm;
  WorkspaceFigures w;
  w.exit_angle_rad = phi_rad_;
  // eϕ: the stylet chord 2R sin(zs/2R) turned by ϕ about the exit point (eq 6).
  w.exit_error_mm = 4.0 * R * std::sin(zs / (2.0 * R)) * std::sin(0.5 * phi_rad_);
  const double reach = R * (1.0 - std::cos(zs / R));
  w.volume_paper_cm3 = kPi * zc * reach * reach / 1000.0;  // eq (18)
  w.zone_diameter_paper_mm = 2.0 * reach;                  // eq (19)
  w.r_min_mm = r_min_mm_;
  w.r_max_mm = r_max_mm_;
  // Every radius in [r_min, r_max] is reached by exactly one zs, and z then spans zc_max.
  w.volume_exact_cm3 = kPi * zc * (r_max_mm_ * r_max_mm_ - r_min_mm_ * r_min_mm_) / 1000.0;
  return w;
}

}  // namespace ignav::kinematics
