// A needle in a world the server does not model (issue 40): what the built-in confirmation phantom
// uses to decide where a needle really goes, so that compensation is judged against physics other
// than the extended bicycle model the server fits. docs/VERIFICATION.md, "Two worlds".
//
// The instrument is two elastic rods pushed through tissue that resists them:
// - the cannula (bending stiffness EI_c) is a beam on an elastic (Winkler) foundation whose
//   stiffness changes with depth in layers; a lateral force at its tip (the stylet's bevel sits
//   off-centre in the cannula's bore) pushes it aside as it goes, and the tissue holds every part
//   of it in the channel its tip cut on the way in (quasi-static, the insertion in 0.5 mm steps,
//   finite differences). Its own curvature (the stylet inside it, the kinematics' Rd) is followed
//   exactly: a channel cut by the tip of a rod bending its own way holds it without force;
// - the stylet leaves the cannula's real tip at the real tip's heading, tilted by its play in the
//   bore (clearance / grip), along its precurved arc, pushed aside by its own tip force through
//   the same foundation, and its plane winds up (twist per mm, the friction on a nitinol wire);
// - the tissue dragged along relaxes: a seed is left short of the tip in proportion to the
//   length pushed in;
// - per insertion, a little randomness: the cannula's rotation (θc error), backlash of both
//   translations, the play's share, the robot mount's jitter.
// None of this is the extended bicycle model: layers, memory of the channel, exit play, twist and
// drag have no (λ1, λ2) that reproduces them. Pure: values in, values out; deterministic for a
// world's seed and an insertion's number.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/kinematics/solver.hpp"

namespace ignav::needle_world {

struct TissueLayer {
  std::string name;
  double from_depth_mm = 0.0;         // its top, along the insertion from the skin
  double stiffness_n_per_mm2 = 0.02;  // the foundation's modulus: N per mm of needle per mm
};

struct RodWorld {
  std::string name;
  std::string source;                       // where the values come from, for a person
  double cannula_stiffness_nmm2 = 63000.0;  // EI: a steel tube 2.10/1.90 mm, E = 200 GPa
  double stylet_stiffness_nmm2 = 6100.0;    // EI: nitinol 1.20 mm, E ≈ 60 GPa
  double cannula_tip_force_n = 0.3;         // towards the stylet's curve (+y′)
  double stylet_tip_force_n = 0.05;         // towards the inside of its curve
  // The stylet's length bearing in the bore: it may leave tilted by up to the radial clearance
  // (the robot's cannula bore less the stylet, halved) over this length.
  double stylet_grip_mm = 15.0;
  double exit_play_bias = 0.5;                  // the play used towards the curve (0..1)
  double twist_rad_per_mm = 0.05 * M_PI / 180;  // the stylet's plane winding up as it goes
  double drag_shortfall_per_mm = 0.01;          // seed left short per mm pushed in
  std::vector<TissueLayer> layers{{"gel", 0.0, 0.02}};
  // Per insertion (SDs, except backlash: uniform in [0, backlash_mm] short of the command).
  double rotation_sd_rad = 0.3 * M_PI / 180;
  double backlash_mm = 0.15;
  double exit_play_sd = 0.3;
  double mount_sd_mm = 0.05;
  std::uint64_t seed = 1;
};

// Where one insertion went, robot frame.
struct WorldNeedle {
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();       // the stylet's tip
  Eigen::Vector3d direction = -Eigen::Vector3d::UnitZ();  // its tangent there, into the body
  Eigen::Vector3d seed_mm = Eigen::Vector3d::Zero();      // where a seed is left (drag)
  Eigen::Vector3d cannula_tip_mm = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> cannula_mm;  // from above_mm above the skin to its tip
  std::vector<Eigen::Vector3d> stylet_mm;   // from where it leaves the cannula to its tip
  kinematics::Joints joints;                // as the mechanism really turned and moved
  double cannula_deviation_mm = 0.0;        // the cannula tip's sideways push by the tissue
};

// Errors: a world whose values are not physical (non-finite, stiffness ≤ 0, layers out of order,
// negative SDs), non-finite joints.
Status checkWorld(const RodWorld& world);
// `insertion` numbers the insertion (its randomness); the cannula is given from `above_mm` above
// the skin (a scan shows it up to the robot).
Expected<WorldNeedle> insertNeedle(const RodWorld& world, const kinematics::Kinematics& kinematics,
                                   const kinematics::Joints& commanded, std::uint64_t insertion,
                                   double above_mm = 0.0);

// A world file (configs/worlds/*.yaml); errors name the file and the key.
Expected<RodWorld> loadRodWorld(const std::string& path);

// The lateral deviation of a beam (bending stiffness EI) pushed `length_mm` into the layers,
// starting `depth0_mm` below the skin, by a force at its tip, clamped where it enters and held by
// the tissue in the channel its tip cut (the insertion in steps of `step_mm`). Exposed for tests:
// without a foundation it is a cantilever, whose deflection has a closed form.
struct BeamDeviation {
  std::vector<double> lateral_mm;  // at 0, step, 2·step, ... along the beam; the tip last
  double tip_angle_rad = 0.0;
};
BeamDeviation pushBeam(double ei_nmm2, double tip_force_n, double length_mm, double depth0_mm,
                       double step_mm, const std::vector<TissueLayer>& layers);

}  // namespace ignav::needle_world
