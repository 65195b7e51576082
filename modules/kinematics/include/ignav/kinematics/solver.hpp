// Forward and inverse kinematics, reachability and feasible-volume figures of the instrument.
// Equations and conventions: MODEL.md §3-7 (the paper's misprints corrected there).
#pragma once

#include <string>

#include "ignav/core/expected.hpp"
#include "ignav/kinematics/instrument.hpp"

namespace ignav::kinematics {

// Why a target cannot be reached (MODEL.md §5, reason codes 1-4).
enum class Reach { kReachable, kInsideMinRadius, kBeyondMaxRadius, kTooShallow, kTooDeep };

const char* toString(Reach reach);  // "reachable", "inside_min_radius", ...

struct InverseSolution {
  Reach reach = Reach::kReachable;
  // The exact joints when reachable. When too shallow/deep, the joints that put the tip at the
  // target's radius (z_c outside its range); when the radius is out of range, zero.
  Joints joints;
  // How far the target lies outside the limit that failed (mm), 0 when reachable.
  double excess_mm = 0.0;
  bool reachable() const { return reach == Reach::kReachable; }
};

// The paper's closed form (eqs 16 and corrected 17): small-angle approximations, no exit offset.
struct ClosedFormSolution {
  Joints joints;          // as the formulas give them, possibly outside the joint ranges
  bool clipped = false;   // true when joints had to be clipped to their ranges for FK
  Joints clipped_joints;  // joints clipped to their ranges
  double error_mm = 0.0;  // |FK(clipped_joints) - target| with the full model
};

struct WorkspaceFigures {
  double exit_angle_rad = 0.0;          // ϕ, eq (5)
  double exit_error_mm = 0.0;           // eϕ, eq (6)/(20)
  double volume_paper_cm3 = 0.0;        // eq (18)
  double zone_diameter_paper_mm = 0.0;  // eq (19)
  double r_min_mm = 0.0;                // tip radius at z_s = 0
  double r_max_mm = 0.0;                // tip radius at z_s = zs_max
  double volume_exact_cm3 = 0.0;        // π·zc_max·(r_max² - r_min²)
};

// One instrument with its derived constants precomputed; cheap to copy, immutable.
class Kinematics {
 public:
  // Validates the geometry (errors name the YAML key, e.g. "robot.stylet.radius_mm").
  static Expected<Kinematics> create(const Instrument& instrument);

  const Instrument& instrument() const { return instrument_; }
  double exitAngle_rad() const { return phi_rad_; }
  double minRadius_mm() const { return r_min_mm_; }
  double maxRadius_mm() const { return r_max_mm_; }

  // Joints must be finite; values outside the ranges are computed, not clamped (see checkJoints).
  TipPose forward(const Joints& joints) const;
  // The same pose's whole centreline, sampled about every step_mm of arc (step_mm > 0; the ends
  // are forward()'s cannula tip and tip exactly).
  Centreline centreline(const Joints& joints, double step_mm) const;

  // Exact inverse: the paper's closed form refined by safeguarded Newton iterations on the
  // monotone tip radius r(z_s). Errors only for a non-finite target.
  Expected<InverseSolution> inverse(const Eigen::Vector3d& target_mm) const;

  // The paper's joints alone (cheap; may lie outside the joint ranges).
  Joints closedFormJoints(const Eigen::Vector3d& target_mm) const;
  // The same joints, clipped and scored against the full forward model.
  ClosedFormSolution inverseClosedForm(const Eigen::Vector3d& target_mm) const;

  // The z_s in [0, zs_max] whose tip radius equals radius_mm (which must lie in
  // [r_min, r_max]). Exposed for the workspace map, which solves once per (x, y) column.
  double styletForRadius_mm(double radius_mm) const;
  // Tip depth z' at z_c = 0 for a stylet deployment; z = z0 - z_c.
  double tipDepthAtHome_mm(double z_s_mm) const;

  WorkspaceFigures workspace() const;

  // Names the joint, value and range that is violated, e.g.
  // "z_c_mm = 41.000 is outside the cannula travel [0, 40] mm".
  Status checkJoints(const Joints& joints) const;

  // A person-readable reason, e.g. "target (12.0, -3.5, -180.2) mm is 3.2 mm beyond the maximum
  // radius 26.5 mm".
  std::string describe(const InverseSolution& solution, const Eigen::Vector3d& target_mm) const;

 private:
  struct Planar {
    double y_mm, z_mm;  // tip in the rotated plane at z_c = 0
    double cannula_y_mm, cannula_z_mm;
    double gamma_rad;
  };
  // The deflected cannula for a stylet deployment: its arc angle θd and its tip P2 (eqs 3, 4).
  struct CannulaBend {
    double theta_d_rad, sin_d, cos_d;
    double tip_y_mm, tip_z_mm;  // at z_c = 0
  };
  CannulaBend cannulaBend(double z_s_mm) const;
  Planar planar(double z_s_mm, ExitOffset offset) const;
  // Tip radius r(z_s) and its first two derivatives, for the root finder.
  struct RadialProfile {
    double radius_mm, slope, curvature;
  };
  RadialProfile radialProfile(double z_s_mm) const;
  double closedFormStylet_mm(double radius_mm) const;

  explicit Kinematics(const Instrument& instrument);

  Instrument instrument_;
  bool rigid_ = false;
  double inv_rd_ = 0.0;        // 1/Rd, 0 for a rigid cannula
  double clearance_mm_ = 0.0;  // c = (dc - ds)/2
  double phi_rad_ = 0.0, cos_phi_ = 1.0, sin_phi_ = 0.0;
  double r_min_mm_ = 0.0, r_max_mm_ = 0.0;
  // Closed-form constants (eq 15)
  double cf_m_ = 0.0, cf_n_ = 0.0, cf_den_ = 0.0;
};

}  // namespace ignav::kinematics
