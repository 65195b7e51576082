// What a pose of the robot covers of a target structure (robot_placement.hpp).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

#include "ignav/anatomy/clearance.hpp"
#include "ignav/placement/robot_placement.hpp"

namespace ignav::placement {
namespace {

// Centreline samples: a chord of 1 mm strays 3.5 µm from the stylet's 35.5 mm arc.
constexpr double kCentrelineStep_mm = 1.0;
// The closest approach is searched at this spacing where the needle is near a structure (as the
// session's clearance does).
constexpr double kSearchStep_mm = 0.1;
// The reach table's radii: the tip depth at home varies smoothly with the radius (a few mm over
// the whole range), so 1024 rows put interpolation errors in the micrometres.
constexpr int kTableRows = 1024;

}  // namespace

RobotPose RobotPose::along(const Eigen::Vector3d& origin_lps_mm,
                           const Eigen::Vector3d& insertion_lps) {
  RobotPose pose;
  pose.origin_lps_mm = origin_lps_mm;
  const Eigen::Vector3d z = -insertion_lps.normalized();
  const Eigen::Vector3d reference =
      std::abs(z.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d x = (reference - reference.dot(z) * z).normalized();
  pose.rotation.col(0) = x;
  pose.rotation.col(1) = z.cross(x);
  pose.rotation.col(2) = z;
  return pose;
}

RobotPose RobotPose::of(const registration::Registration& registration) {
  RobotPose pose;
  pose.origin_lps_mm = registration.toImage(Eigen::Vector3d::Zero());
  // p_robot = s R p + t: the robot's axes in the image are R's rows.
  pose.rotation = registration.rotation.transpose();
  return pose;
}

Eigen::Matrix4d RobotPose::imageToRobot() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = rotation.transpose();
  m.topRightCorner<3, 1>() = -rotation.transpose() * origin_lps_mm;
  return m;
}

Expected<CoverageModel> CoverageModel::create(CoverageInputs inputs, double sample_mm) {
  if (!inputs.kinematics) {
    return makeError(ErrorCode::kInvalidArgument, "placement: no robot kinematics");
  }
  if (!inputs.target || inputs.target->mask.count() == 0) {
    return makeError(ErrorCode::kInvalidArgument, "placement: the target structure is empty",
                     "empty_structure");
  }
  if (!std::isfinite(sample_mm) || sample_mm <= 0.0 || sample_mm > 20.0) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("placement: a sample spacing of {} mm is outside (0, 20] mm", sample_mm));
  }
  for (const auto& a : inputs.avoided) {
    if (!a.field) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("placement: '{}' has no distance field", a.name));
    }
  }
  // A CT without its voxels (a grid alone) shows no skin: no skin is checked.
  if (inputs.ct && inputs.ct->voxels.empty()) inputs.ct.reset();
  CoverageModel model;
  model.sample_mm_ = sample_mm;
  const auto& mask = inputs.target->mask;
  const auto& g = mask.geometry;
  std::array<int, 3> stride{};
  for (int a = 0; a < 3; ++a)
    stride[static_cast<std::size_t>(a)] =
        std::max(1, static_cast<int>(std::lround(sample_mm / g.spacing_mm[a])));
  // The lattice's phase: centred in the box, so the samples do not all sit on one face.
  std::array<int, 3> phase{};
  for (std::size_t a = 0; a < 3; ++a)
    phase[a] = ((g.dims[a] - 1) / 2) % stride[a];
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::size_t inside = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        if (!mask.inside[mask.index(i, j, k)]) continue;
        const Eigen::Vector3d p = g.toLps(Eigen::Vector3d(i, j, k));
        sum += p;
        ++inside;
        if (i % stride[0] == phase[0] && j % stride[1] == phase[1] && k % stride[2] == phase[2])
          model.samples_lps_mm_.push_back(p);
      }
  model.centroid_lps_mm_ = sum / static_cast<double>(inside);
  if (model.samples_lps_mm_.empty()) model.samples_lps_mm_.push_back(model.centroid_lps_mm_);

  std::vector<Eigen::Vector3d> markers(inputs.markers_robot_mm.begin(),
                                       inputs.markers_robot_mm.end());
  model.markers_ = registration::describeFiducials(markers);

  const auto& kin = *inputs.kinematics;
  const double r_min = kin.minRadius_mm(), r_max = kin.maxRadius_mm();
  model.table_step_mm_ = (r_max - r_min) / (kTableRows - 1);
  for (int n = 0; n < kTableRows; ++n) {
    const double r = std::min(r_max, r_min + n * model.table_step_mm_);
    model.depth_table_mm_.push_back(kin.tipDepthAtHome_mm(kin.styletForRadius_mm(r)));
  }
  model.inputs_ = std::move(inputs);
  return model;
}

double CoverageModel::depthAtHome_mm(double radius_mm) const {
  const double r_min = inputs_.kinematics->minRadius_mm();
  const double x = (radius_mm - r_min) / table_step_mm_;
  if (!(x >= 0.0) || x > kTableRows - 1) return std::numeric_limits<double>::quiet_NaN();
  const auto row = std::min(static_cast<std::size_t>(x), depth_table_mm_.size() - 2);
  const double f = x - static_cast<double>(row);
  return depth_table_mm_[row] + f * (depth_table_mm_[row + 1] - depth_table_mm_[row]);
}

// The needle comes closest to a structure within its field's box (beyond it, the field's reach
// exceeds any margin and uncertainty), where the expected registration error, a convex quadratic,
// is largest at a corner: per avoided structure, that largest error for this pose.
std::vector<double> CoverageModel::largestTre_mm(const RobotPose& pose) const {
  std::vector<double> out;
  for (const auto& avoided : inputs_.avoided) {
    const auto& grid = avoided.field->grid();
    double tre_max_mm = 0.0;
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3d ijk((corner & 1) ? grid.dims[0] - 1 : 0,
                                (corner & 2) ? grid.dims[1] - 1 : 0,
                                (corner & 4) ? grid.dims[2] - 1 : 0);
      tre_max_mm =
          std::max(tre_max_mm, registration::expectedTre_mm(markers_, pose.toRobot(grid.toLps(ijk)),
                                                            inputs_.fle_mm, inputs_.kind));
    }
    out.push_back(tre_max_mm);
  }
  return out;
}

int CoverageModel::judge(const RobotPose& pose, const Eigen::Vector3d& lps_mm) const {
  return judge(pose, lps_mm, largestTre_mm(pose));
}

int CoverageModel::judge(const RobotPose& pose, const Eigen::Vector3d& lps_mm,
                         const std::vector<double>& largest_tre_mm) const {
  const auto& kin = *inputs_.kinematics;
  const auto solution = kin.inverse(pose.toRobot(lps_mm));
  if (!solution || !solution->reachable()) return -1;
  if (inputs_.avoided.empty()) return 0;
  const auto& joints = solution->joints;
  const auto centreline = kin.centreline(joints, kCentrelineStep_mm);
  anatomy::NeedleBody body(2);
  body[0].centreline_lps_mm.reserve(centreline.cannula_mm.size());
  for (const auto& p : centreline.cannula_mm)
    body[0].centreline_lps_mm.push_back(pose.toImage(p));
  for (const auto& p : centreline.stylet_mm)
    body[1].centreline_lps_mm.push_back(pose.toImage(p));
  const auto& instrument = kin.instrument();
  body[0].radius_mm = 0.5 * instrument.cannula_outer_diameter_mm;
  body[1].radius_mm = 0.5 * instrument.stylet_outer_diameter_mm;

  double drift_mm = 0.0;
  if (const auto& d = inputs_.drift_mm_by_z_c; !d.empty()) {
    const double x = std::clamp(joints.z_c_mm, 0.0, static_cast<double>(d.size() - 1));
    const auto row = std::min(static_cast<std::size_t>(x), d.size() > 1 ? d.size() - 2 : 0);
    drift_mm =
        d.size() > 1 ? d[row] + (x - static_cast<double>(row)) * (d[row + 1] - d[row]) : d[0];
  }
  for (std::size_t n = 0; n < inputs_.avoided.size(); ++n) {
    const auto& avoided = inputs_.avoided[n];
    // A body that stays farther than the margin and the largest uncertainty is cleared at once;
    // only one that may come near is measured exactly, as the session does.
    const double tre_max_mm = largest_tre_mm.at(n);
    const double uncertainty_max_mm = anatomy::clearanceUncertainty_mm(tre_max_mm, 0.0, drift_mm);
    if (anatomy::staysFarther(body, *avoided.field, avoided.margin_mm + uncertainty_max_mm,
                              kSearchStep_mm))
      continue;
    const auto closest = anatomy::closestApproach(body, *avoided.field, kSearchStep_mm);
    if (!std::isfinite(closest.distance_mm)) continue;
    const double tre_mm = registration::expectedTre_mm(
        markers_, pose.toRobot(closest.needle_lps_mm), inputs_.fle_mm, inputs_.kind);
    const double uncertainty_mm = anatomy::clearanceUncertainty_mm(tre_mm, 0.0, drift_mm);
    if (closest.distance_mm - uncertainty_mm < avoided.margin_mm) return 1 + static_cast<int>(n);
  }
  return 0;
}

Coverage CoverageModel::coverage(const RobotPose& pose) const {
  Coverage c;
  c.samples = samples_lps_mm_.size();
  c.too_close.assign(inputs_.avoided.size(), 0);
  const auto largest_tre_mm = largestTre_mm(pose);  // once per pose, not per sample
  for (const auto& p : samples_lps_mm_) {
    const int verdict = judge(pose, p, largest_tre_mm);
    if (verdict == 0)
      ++c.covered;
    else if (verdict < 0)
      ++c.unreachable;
    else
      ++c.too_close[static_cast<std::size_t>(verdict - 1)];
  }
  return c;
}

SkinEntry CoverageModel::skinEntry(const RobotPose& pose, double skin_hu) const {
  SkinEntry out;
  const Eigen::Vector3d a = pose.insertion();
  // The axis' point level with the target's centroid: the march ends there.
  const Eigen::Vector3d level =
      pose.origin_lps_mm + a * (centroid_lps_mm_ - pose.origin_lps_mm).dot(a);
  if (!inputs_.ct) {
    out.entry_lps_mm = level;
    out.skin_distance_mm = (level - pose.origin_lps_mm).dot(a);
    return out;
  }
  const auto& ct = *inputs_.ct;
  const auto& g = ct.geometry;
  const Eigen::Vector3d extent =
      g.direction * (g.spacing_mm.cwiseProduct(Eigen::Vector3d(g.dims[0], g.dims[1], g.dims[2])));
  const Eigen::Vector3d centre =
      g.toLps(0.5 * Eigen::Vector3d(g.dims[0] - 1, g.dims[1] - 1, g.dims[2] - 1));
  const double from = (level - centre).norm() + 0.5 * extent.norm() + 1.0;
  constexpr double kStep_mm = 1.0;
  const double lowest = std::numeric_limits<double>::lowest();
  bool in_ct = false;
  double t_prev = from;
  for (double t = from; t >= 0.0; t -= kStep_mm) {  // t: distance before `level`
    const Eigen::Vector3d x = level - t * a;
    if (g.outsideBy_mm(x) > 0.0) {
      t_prev = t;
      continue;
    }
    const bool tissue = ct.sampleLps(x, lowest) >= skin_hu;
    if (!in_ct) {  // the CT's edge: the skin is there or before it
      in_ct = true;
      out.entry_lps_mm = x;
      if (tissue) break;  // the CT cuts the body here: its skin is not imaged
    }
    if (tissue) {
      // Between the sample before (below) and this one: halve down to 1/32 mm.
      double lo = t_prev, hi = t;
      for (int n = 0; n < 5; ++n) {
        const double mid = 0.5 * (lo + hi);
        (ct.sampleLps(level - mid * a, lowest) >= skin_hu ? hi : lo) = mid;
      }
      out.entry_lps_mm = level - hi * a;
      out.seen = true;
      break;
    }
    t_prev = t;
  }
  if (!in_ct) out.entry_lps_mm = level;
  out.skin_distance_mm = (out.entry_lps_mm - pose.origin_lps_mm).dot(a);
  return out;
}

PoseDeviation deviation(const PlacedPose& proposed, const RobotPose& mounted,
                        const SkinEntry& mounted_skin) {
  PoseDeviation d;
  d.entry_mm = (mounted_skin.entry_lps_mm - proposed.skin.entry_lps_mm).norm();
  const double cosine = std::clamp(mounted.insertion().dot(proposed.pose.insertion()), -1.0, 1.0);
  d.axis_deg = std::acos(cosine) * 180.0 / M_PI;
  d.depth_mm = (mounted.origin_lps_mm - proposed.pose.origin_lps_mm).dot(proposed.pose.insertion());
  return d;
}

}  // namespace ignav::placement
