// Where to place the robot (issue 41, part 4): on a planning CT taken before the robot is
// mounted, the pose (entry point on the skin, insertion axis) from which one insertion reaches
// the most of a target structure with every clearance kept, within the limits a site gives; and
// what a mounted robot's pose covers. Pure: values in, values out; the server runs it on its job
// thread.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/anatomy/distance_field.hpp"
#include "ignav/anatomy/site.hpp"
#include "ignav/anatomy/structures.hpp"
#include "ignav/core/expected.hpp"
#include "ignav/kinematics/solver.hpp"
#include "ignav/registration/feature_points.hpp"
#include "ignav/registration/point_registration.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::placement {

using anatomy::PlacementLimits;  // the site's (site.hpp)

// A pose of the robot on the patient: robot -> image (LPS) is p = origin + rotation * q, rigid.
// The robot inserts along its -Z, so `insertion()` is rotation's third column negated.
struct RobotPose {
  Eigen::Vector3d origin_lps_mm = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();

  // A pose inserting along `insertion_lps` with its origin there. The roll about the axis is a
  // convention (the robot's +X as close to LPS +L as the axis lets it): the cannula turns
  // through 360°, so a roll changes no reach and no clearance.
  static RobotPose along(const Eigen::Vector3d& origin_lps_mm,
                         const Eigen::Vector3d& insertion_lps);
  // The pose a registration found (its scale, within 10 % of 1, set aside).
  static RobotPose of(const registration::Registration& registration);

  Eigen::Vector3d insertion() const { return -rotation.col(2); }
  Eigen::Vector3d toImage(const Eigen::Vector3d& robot_mm) const {
    return origin_lps_mm + rotation * robot_mm;
  }
  Eigen::Vector3d toRobot(const Eigen::Vector3d& lps_mm) const {
    return rotation.transpose() * (lps_mm - origin_lps_mm);
  }
  Eigen::Matrix4d imageToRobot() const;
};

// A structure the needle keeps away from, with its distance field (at least margin + the
// uncertainty's reach around it).
struct AvoidedStructure {
  std::string name;
  std::shared_ptr<const anatomy::DistanceField> field;
  double margin_mm = 0.0;
};

// What decides whether a point of the target is covered from a pose: the instrument, the
// structures to avoid, and the uncertainty that widens each margin as the session's clearance
// does it (twice the expected registration error per direction, from the robot's own markers
// and their localisation error, plus the deflection the session's tissue predicts unaimed).
struct CoverageInputs {
  std::shared_ptr<const kinematics::Kinematics> kinematics;
  registration::FeaturePoints markers_robot_mm{};  // the registration's fiducials
  double fle_mm = 0.5;
  registration::TransformKind kind = registration::TransformKind::kSimilarity;
  // The tissue's predicted sideways drift (mm) by cannula insertion z_c, every 1 mm from 0;
  // empty: no tissue.
  std::vector<double> drift_mm_by_z_c;
  std::shared_ptr<const anatomy::Structure> target;
  std::vector<AvoidedStructure> avoided;
  std::shared_ptr<const volume::Volume> ct;  // for the skin; may be null (no skin check)
};

// How much of the target a pose covers: samples of its voxels (a lattice, each standing for the
// same volume), counted by why they are not covered.
struct Coverage {
  std::size_t samples = 0;
  std::size_t covered = 0;
  std::size_t unreachable = 0;
  std::vector<std::size_t> too_close;  // per avoided structure (the first too close)
  double fraction() const {
    return samples ? static_cast<double>(covered) / static_cast<double>(samples) : 0.0;
  }
};

// Where the axis meets the skin, for a pose.
struct SkinEntry {
  Eigen::Vector3d entry_lps_mm = Eigen::Vector3d::Zero();
  double skin_distance_mm = 0.0;  // from the robot's origin to the entry, along the axis
  bool seen = false;  // false: the CT shows no skin on the axis; its edge stands in for it
};

class CoverageModel {
 public:
  // The target's voxels sampled on a lattice about `sample_mm` apart (whole voxels: at least
  // one). Errors name what is missing or out of range.
  static Expected<CoverageModel> create(CoverageInputs inputs, double sample_mm);

  std::size_t samples() const { return samples_lps_mm_.size(); }
  const std::vector<Eigen::Vector3d>& samplePoints() const { return samples_lps_mm_; }
  double sample_mm() const { return sample_mm_; }
  const Eigen::Vector3d& targetCentroid() const { return centroid_lps_mm_; }
  const CoverageInputs& inputs() const { return inputs_; }

  // One point from one pose: 0 covered, -1 out of reach, else 1 + the avoided structure the
  // needle's body comes too close to (the first in order).
  int judge(const RobotPose& pose, const Eigen::Vector3d& lps_mm) const;
  Coverage coverage(const RobotPose& pose) const;
  // Along the pose's axis from outside the CT towards the target's centroid.
  SkinEntry skinEntry(const RobotPose& pose, double skin_hu) const;

  // Reach only, on a table of the feasible volume by radius (no clearance): the robot z-range
  // of the tips at radius r is [depth_at_home(r) - zc_max, depth_at_home(r)]; NaN when r lies
  // outside [r_min, r_max]. For the coarse search.
  double depthAtHome_mm(double radius_mm) const;

 private:
  std::vector<double> largestTre_mm(const RobotPose& pose) const;
  int judge(const RobotPose& pose, const Eigen::Vector3d& lps_mm,
            const std::vector<double>& largest_tre_mm) const;
  CoverageInputs inputs_;
  double sample_mm_ = 0.0;
  std::vector<Eigen::Vector3d> samples_lps_mm_;
  Eigen::Vector3d centroid_lps_mm_ = Eigen::Vector3d::Zero();
  registration::FiducialConfiguration markers_;
  std::vector<double> depth_table_mm_;  // depth at home by radius, r_min to r_max
  double table_step_mm_ = 0.0;
};

// A pose with what it covers and where it enters.
struct PlacedPose {
  RobotPose pose;
  Coverage coverage;
  SkinEntry skin;
  double tilt_deg = 0.0;  // from the site's insertion direction
  double shift_mm = 0.0;  // from the target's centroid to the axis
};

struct Placement {
  std::vector<PlacedPose> poses;  // the best first, then distinct alternatives
  std::size_t evaluations = 0;    // full coverage evaluations made
  std::size_t samples = 0;        // of the target, in the final figures
};

// (done, total) as the search goes.
using Progress = std::function<void(std::size_t, std::size_t)>;

// The search: every direction within the tilt limit (5° apart or finer) and every axis 2 mm
// apart within the shift limit, the best depth of each by reach alone (an exact sweep over the
// depths); from the best distinct of these, a pattern search on the full coverage (reach and
// every clearance); the poses found judged again on `final_model` (a finer lattice), with up to
// `alternatives` others at least 5 mm or 5° from every better one. Errors when no pose keeps
// the robot outside the skin.
Expected<Placement> placeRobot(const CoverageModel& search_model, const CoverageModel& final_model,
                               const PlacementLimits& limits, std::size_t alternatives = 3,
                               const Progress& progress = {});

// A reference for the search (tests, benchmarks): every pose of a grid, full coverage each.
struct PoseGrid {
  double tilt_step_deg = 5.0;  // tilt levels 0, step, ... up to the limit; azimuths as far apart
  double shift_step_mm = 4.0;  // axis offsets on a square grid within the shift limit
  double depth_step_mm = 4.0;  // depths over every one where the feasible volume meets the target
  unsigned threads = 1;
};
PlacedPose bruteForcePlacement(const CoverageModel& model, const PlacementLimits& limits,
                               const PoseGrid& grid, std::size_t* poses_tried = nullptr);

// How far a mounted robot is from a proposed pose: its entry on the skin and its axis.
struct PoseDeviation {
  double entry_mm = 0.0;  // between the entries on the skin
  double axis_deg = 0.0;  // between the insertion axes
  double depth_mm = 0.0;  // the origins' difference along the proposed axis (+: deeper)
};
PoseDeviation deviation(const PlacedPose& proposed, const RobotPose& mounted,
                        const SkinEntry& mounted_skin);

}  // namespace ignav::placement
