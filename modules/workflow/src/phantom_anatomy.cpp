// The built-in phantom's anatomy (issue 41): a prostate-like target volume filling the robot's
// feasible volume, a urethra through it, a rectum behind it and a pubic arch in front, placed in
// the robot's frame (background_jobs.hpp).
#include <algorithm>
#include <cmath>

#include "ignav/workflow/background_jobs.hpp"

namespace ignav::workflow {
namespace {

// Signed distance to a cylinder of `radius` around the segment a-b (flat ends).
double cappedCylinder(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                      double radius) {
  const Eigen::Vector3d axis = (b - a).normalized();
  const double length = (b - a).norm();
  const double t = (p - a).dot(axis);
  const double radial = ((p - a) - t * axis).norm() - radius;
  const double along = std::max(-t, t - length);
  const Eigen::Vector2d outside(std::max(radial, 0.0), std::max(along, 0.0));
  return std::min(std::max(radial, along), 0.0) + outside.norm();
}

// A bound on the distance to an ellipsoid (exact on its axes): its scaled distance times the
// least semi-axis. Only its sign matters here (the masks).
double ellipsoid(const Eigen::Vector3d& p, const Eigen::Vector3d& centre,
                 const Eigen::Vector3d& semi_axes) {
  const double k = ((p - centre).array() / semi_axes.array()).matrix().norm();
  return (k - 1.0) * semi_axes.minCoeff();
}

}  // namespace

std::vector<anatomy::Shape> phantomAnatomy(const kinematics::Kinematics& kin) {
  const double r_max = kin.maxRadius_mm();
  const auto& instrument = kin.instrument();
  // The feasible volume's depth: the shallowest tip (no cannula travel) to the deepest.
  double top = -1e9, bottom = 1e9;
  for (int i = 0; i <= 20; ++i) {
    const double z = kin.tipDepthAtHome_mm(instrument.stylet_travel_mm * i / 20.0);
    top = std::max(top, z);
    bottom = std::min(bottom, z - instrument.cannula_travel_mm);
  }
  const double mid = 0.5 * (top + bottom), half = 0.5 * (top - bottom);
  const Eigen::Vector3d centre(0.0, 0.0, mid);
  const Eigen::Vector3d urethra(0.55 * r_max, 0.0, 0.0);
  const double rectum_y = -(r_max + 12.0);
  const double arch_y = r_max + 6.0;
  return {
      {"prostate",
       {0.85, 0.60, 0.40},
       anatomy::Role::kTarget,
       0.0,
       [=](const Eigen::Vector3d& p) {
         return ellipsoid(p, centre, Eigen::Vector3d(0.95 * r_max, 0.95 * r_max, 0.9 * half));
       }},
      {"urethra",
       {1.00, 0.90, 0.20},
       anatomy::Role::kAvoid,
       3.0,
       [=](const Eigen::Vector3d& p) {
         return cappedCylinder(p, urethra + Eigen::Vector3d(0, 0, bottom - 15.0),
                               urethra + Eigen::Vector3d(0, 0, top + 15.0), 3.0);
       }},
      {"rectum",
       {0.60, 0.35, 0.25},
       anatomy::Role::kAvoid,
       5.0,
       [=](const Eigen::Vector3d& p) {
         return cappedCylinder(p, Eigen::Vector3d(0, rectum_y, bottom - 15.0),
                               Eigen::Vector3d(0, rectum_y, top + 15.0), 8.0);
       }},
      {"pubic_arch",
       {0.95, 0.95, 0.85},
       anatomy::Role::kAvoid,
       2.0,
       [=](const Eigen::Vector3d& p) {
         return cappedCylinder(p, Eigen::Vector3d(-30.0, arch_y, top + 6.0),
                               Eigen::Vector3d(30.0, arch_y, top + 6.0), 4.0);
       }},
  };
}

}  // namespace ignav::workflow
