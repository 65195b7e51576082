// One insertion in the rod-in-tissue world (rod_world.hpp).
#include <algorithm>
#include <cmath>
#include <random>

#include <fmt/format.h>

#include <Eigen/Geometry>

#include "ignav/kinematics/plane.hpp"
#include "ignav/needle_world/rod_world.hpp"

namespace ignav::needle_world {
namespace {

constexpr double kStep_mm = 0.5;  // the insertion's steps and the beams' nodes
constexpr double kShapeStep_mm = 0.25;

using Plane = kinematics::ThetaPlane;

// The deviation at `along_mm` of a beam sampled every `step` from its start.
double at(const BeamDeviation& beam, double along_mm, double step) {
  if (beam.lateral_mm.size() < 2 || along_mm <= 0.0) return 0.0;
  const double x = std::min(along_mm / step, static_cast<double>(beam.lateral_mm.size() - 1));
  const auto i = std::min(static_cast<std::size_t>(x), beam.lateral_mm.size() - 2);
  const double t = x - static_cast<double>(i);
  return (1.0 - t) * beam.lateral_mm[i] + t * beam.lateral_mm[i + 1];
}

double stepOf(double length_mm) {
  return length_mm > 0.0 ? length_mm / std::max(1.0, std::ceil(length_mm / kStep_mm - 1e-9))
                         : kStep_mm;
}

}  // namespace

Status checkWorld(const RodWorld& w) {
  auto bad = [&](const std::string& what) {
    return makeError(ErrorCode::kInvalidArgument, fmt::format("world '{}': {}", w.name, what));
  };
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  auto nonNegative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!positive(w.cannula_stiffness_nmm2) || !positive(w.stylet_stiffness_nmm2))
    return bad("bending stiffnesses must be finite and positive");
  if (!std::isfinite(w.cannula_tip_force_n) || !std::isfinite(w.stylet_tip_force_n))
    return bad("tip forces must be finite");
  if (!positive(w.stylet_grip_mm)) return bad("stylet_grip_mm must be finite and > 0");
  if (!(w.exit_play_bias >= 0.0 && w.exit_play_bias <= 1.0))
    return bad(fmt::format("exit_play_bias = {} must lie in [0, 1]", w.exit_play_bias));
  if (!std::isfinite(w.twist_rad_per_mm) || !nonNegative(w.drag_shortfall_per_mm) ||
      w.drag_shortfall_per_mm > 0.2)
    return bad("twist must be finite and drag_shortfall_per_mm in [0, 0.2]");
  if (!nonNegative(w.rotation_sd_rad) || !nonNegative(w.backlash_mm) ||
      !nonNegative(w.exit_play_sd) || !nonNegative(w.mount_sd_mm))
    return bad("the per-insertion spreads must be finite and ≥ 0");
  if (w.layers.empty()) return bad("at least one tissue layer");
  for (std::size_t i = 0; i < w.layers.size(); ++i) {
    const auto& l = w.layers[i];
    if (!nonNegative(l.stiffness_n_per_mm2) || !nonNegative(l.from_depth_mm))
      return bad(fmt::format("layer {} ('{}'): depth and stiffness must be finite and ≥ 0", i + 1,
                             l.name));
    if (i > 0 && !(l.from_depth_mm > w.layers[i - 1].from_depth_mm))
      return bad(fmt::format("layer {} ('{}') must start deeper than layer {}", i + 1, l.name, i));
  }
  return Ok{};
}

Expected<WorldNeedle> insertNeedle(const RodWorld& world, const kinematics::Kinematics& kinematics,
                                   const kinematics::Joints& commanded, std::uint64_t insertion,
                                   double above_mm) {
  if (auto ok = checkWorld(world); !ok) return ok.error();
  if (!std::isfinite(commanded.theta_c_rad) || !std::isfinite(commanded.z_c_mm) ||
      !std::isfinite(commanded.z_s_mm)) {
    return makeError(ErrorCode::kInvalidArgument, "joints must be finite");
  }
  // This insertion's luck, the same every time for the world's seed and its number.
  std::mt19937_64 rng(world.seed * 0x9E3779B97F4A7C15ull + insertion);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  WorldNeedle out;
  kinematics::Joints& j = out.joints;
  j = commanded;
  j.theta_c_rad += world.rotation_sd_rad * normal(rng);
  j.z_c_mm = std::max(0.0, j.z_c_mm - world.backlash_mm * unit(rng));
  j.z_s_mm = std::max(0.0, j.z_s_mm - world.backlash_mm * unit(rng));
  const double play_share =
      std::clamp(world.exit_play_bias + world.exit_play_sd * normal(rng), -1.0, 1.0);
  const Eigen::Vector3d mount =
      world.mount_sd_mm * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));

  const auto nominal = kinematics.centreline(j, kShapeStep_mm);
  const Plane plane(j.theta_c_rad);
  // The cannula: pushed aside by its tip force, held in its channel.
  const double cannula_step = stepOf(j.z_c_mm);
  const BeamDeviation cannula = pushBeam(world.cannula_stiffness_nmm2, world.cannula_tip_force_n,
                                         j.z_c_mm, 0.0, cannula_step, world.layers);
  out.cannula_deviation_mm = cannula.lateral_mm.back();
  const double length_mm = nominal.cannula_arc_mm.back();
  for (std::size_t i = 0; i < nominal.cannula_mm.size(); ++i) {
    const double behind_tip_mm = length_mm - nominal.cannula_arc_mm[i];
    if (behind_tip_mm > j.z_c_mm + std::max(above_mm, 0.0) + 1e-9) continue;  // in the robot
    const double depth_mm = j.z_c_mm - behind_tip_mm;
    out.cannula_mm.push_back(plane.out(plane.in(nominal.cannula_mm[i]) +
                                       Eigen::Vector2d(at(cannula, depth_mm, cannula_step), 0.0)));
  }
  const Eigen::Vector2d nominal_cannula_tip = plane.in(nominal.cannula_mm.back());
  const Eigen::Vector2d cannula_tip =
      nominal_cannula_tip + Eigen::Vector2d(cannula.lateral_mm.back(), 0.0);
  out.cannula_tip_mm = plane.out(cannula_tip);
  // The cannula tip's real heading: the nominal one turned by the tissue's push.
  const Eigen::Vector2d nominal_heading =
      nominal.cannula_mm.size() >= 2 ? (plane.in(nominal.cannula_mm.back()) -
                                        plane.in(nominal.cannula_mm[nominal.cannula_mm.size() - 2]))
                                           .normalized()
                                     : Eigen::Vector2d(0.0, -1.0);
  const Eigen::Vector2d heading = Plane::turned(nominal_heading, cannula.tip_angle_rad);
  const Eigen::Vector3d axis = plane.out(heading).normalized();

  // The stylet: its arc from the real cannula tip, tilted by its play in the bore, pushed aside
  // by its own tip force, its plane winding up as it goes.
  const auto& instrument = kinematics.instrument();
  const double clearance_mm =
      std::max(0.0, instrument.cannula_inner_diameter_mm - instrument.stylet_outer_diameter_mm) / 2;
  const double tilt_rad = cannula.tip_angle_rad + play_share * clearance_mm / world.stylet_grip_mm;
  const double stylet_step = stepOf(j.z_s_mm);
  const BeamDeviation stylet = pushBeam(world.stylet_stiffness_nmm2, world.stylet_tip_force_n,
                                        j.z_s_mm, j.z_c_mm, stylet_step, world.layers);
  double along_mm = 0.0;
  Eigen::Vector2d previous = nominal_cannula_tip;
  std::vector<Eigen::Vector3d>& stylet_mm = out.stylet_mm;
  for (std::size_t k = 0; k < nominal.stylet_mm.size(); ++k) {
    const Eigen::Vector2d q = plane.in(nominal.stylet_mm[k]);
    along_mm += (q - previous).norm();
    previous = q;
    // The arc's inward normal here (towards +y′ where it leaves): (−t_z, t_y) of its tangent.
    const Eigen::Vector2d next =
        k + 1 < nominal.stylet_mm.size() ? plane.in(nominal.stylet_mm[k + 1]) : q;
    const Eigen::Vector2d before = k > 0 ? plane.in(nominal.stylet_mm[k - 1]) : nominal_cannula_tip;
    Eigen::Vector2d tangent = next - before;
    tangent = tangent.norm() > 1e-12 ? tangent.normalized() : heading;
    const Eigen::Vector2d inward(-tangent.y(), tangent.x());
    const Eigen::Vector2d shaped =
        Plane::turned(q - nominal_cannula_tip, tilt_rad) +
        at(stylet, along_mm, stylet_step) * Plane::turned(inward, tilt_rad);
    const Eigen::Vector3d p = plane.out(cannula_tip + shaped);
    const Eigen::AngleAxisd twist(world.twist_rad_per_mm * along_mm, axis);
    stylet_mm.push_back(out.cannula_tip_mm + twist * (p - out.cannula_tip_mm));
  }
  out.tip_mm = stylet_mm.empty() ? out.cannula_tip_mm : stylet_mm.back();
  if (stylet_mm.size() >= 2) {
    out.direction = (stylet_mm.back() - stylet_mm[stylet_mm.size() - 2]).normalized();
  } else {
    out.direction = axis;
  }
  // The tissue dragged along relaxes back: the seed stays short of the tip.
  const double pushed_mm = j.z_c_mm + j.z_s_mm;
  out.seed_mm = out.tip_mm - world.drag_shortfall_per_mm * pushed_mm * out.direction;
  for (auto* line : {&out.cannula_mm, &out.stylet_mm})
    for (auto& p : *line)
      p += mount;
  out.tip_mm += mount;
  out.seed_mm += mount;
  out.cannula_tip_mm += mount;
  return out;
}

}  // namespace ignav::needle_world
