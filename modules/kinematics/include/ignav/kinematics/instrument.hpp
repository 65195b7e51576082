// The steerable-needle instrument: a precurved nitinol stylet inside a straight cannula that the
// stylet itself deflects (docs/KINEMATICS.md, MODEL.md §1-3). Values only.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"

namespace ignav::kinematics {

// Where the stylet leaves the cannula relative to the deflected cannula's centreline (eq. 9,
// MODEL.md A3). kLateral (the lip, perpendicular to the axis) is the physical reading.
enum class ExitOffset { kLateral, kAxial, kNone };

const char* toString(ExitOffset offset);

// Geometry as a user configures it. Field names follow configs/robots/*.yaml.
struct Instrument {
  double stylet_radius_mm = 35.5;              // R, radius of the precurved section
  double stylet_outer_diameter_mm = 1.20;      // ds
  double stylet_travel_mm = 40.0;              // zs_max
  double stylet_curved_length_mm = 40.0;       // L0, largest deflected cannula arc
  double cannula_inner_diameter_mm = 1.90;     // dc
  double cannula_outer_diameter_mm = 2.10;     // only checked against dc
  double cannula_travel_mm = 40.0;             // zc_max
  double cannula_deflected_radius_mm = 550.0;  // Rd; +inf means a rigid cannula
  double cannula_fixed_offset_mm = 95.0;       // z_fixed
  ExitOffset exit_offset = ExitOffset::kLateral;
};

// Joint values. theta_c is the cannula rotation about +Z in [0, 2π); z_c the cannula
// translation (positive = deeper) in [0, zc_max]; z_s the stylet arc beyond the cannula tip in
// [0, zs_max].
struct Joints {
  double theta_c_rad = 0.0;
  double z_c_mm = 0.0;
  double z_s_mm = 0.0;
};

// The robot frame: origin on the cannula axis, +Z out of the body, so every tip has z < 0.
struct TipPose {
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();
  double approach_rad = 0.0;  // γ: angle of the stylet tip from -Z towards the bend
  Eigen::Vector3d cannula_tip_mm = Eigen::Vector3d::Zero();
};

// The instrument's centreline for some joints, robot frame: the cannula from P0 (its proximal
// attachment) down its straight part and its deflected arc to its tip, then the stylet from where
// it leaves the cannula (the clearance offset, eq 9) along its arc to its tip.
struct Centreline {
  std::vector<Eigen::Vector3d> cannula_mm;
  std::vector<double> cannula_arc_mm;  // each cannula point's arc length from P0
  std::vector<Eigen::Vector3d> stylet_mm;
};

}  // namespace ignav::kinematics
