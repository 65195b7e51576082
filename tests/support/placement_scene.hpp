// The built-in phantom as a planning scene for robot placement: its CT (as the server makes it),
// its anatomy with the site's roles, a distance field per avoided structure, coverage models on a
// search and a final lattice, the site's limits for the phantom's approach and the pose the
// phantom's robot stands in. Shared by the placement tests and tools/bench/bench_placement.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/LU>

#include "ignav/anatomy/distance_field.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/placement/robot_placement.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/workflow/background_jobs.hpp"

namespace ignav::test {

struct PlacementScene {
  std::string target_name;
  placement::CoverageModel search, final;
  placement::PlacementLimits limits;
  placement::RobotPose mounted;  // where the phantom's robot stands
};

// What a placement judges coverage by, for `robot`: the set's first target structure, a distance
// field (15 mm, as the server's) for each avoided one, the robot's markers for the uncertainty.
inline placement::CoverageInputs coverageInputs(
    const std::shared_ptr<const anatomy::StructureSet>& set, const config::Robot& robot) {
  placement::CoverageInputs in;
  in.kinematics = std::make_shared<const kinematics::Kinematics>(robot.kinematics);
  in.markers_robot_mm = robot.feature_points_mm;
  in.fle_mm = robot.config.registration.fle_mm;
  for (const auto& s : set->structures) {
    if (s.role == anatomy::Role::kTarget && !in.target)
      in.target = std::shared_ptr<const anatomy::Structure>(set, &s);
    if (s.role == anatomy::Role::kAvoid)
      in.avoided.push_back({s.name,
                            std::make_shared<const anatomy::DistanceField>(
                                anatomy::DistanceField::fromMask(s.mask, 15.0)),
                            s.margin_mm});
  }
  return in;
}

inline Expected<PlacementScene> makePlacementScene(const std::string& robot_config,
                                                   double search_mm = 5.0, double final_mm = 2.5) {
  auto robot = config::loadRobot(robot_config);
  if (!robot) return robot.error();
  auto rp = registration::makeRobotPhantom(robot->kinematics, robot->config.registration.scan);
  if (!rp) return rp.error();
  rp->spec.oblique = true;  // as the server makes it
  rp->spec.noise_sigma_hu = 8.0;
  auto ct = volume::makePhantom(rp->spec);
  if (!ct) return ct.error();
  auto set = anatomy::voxelise(ct->geometry, rp->image_to_robot_true,
                               workflow::phantomAnatomy(robot->kinematics), "phantom:");
  if (!set) return set.error();
  auto shared_set = std::make_shared<const anatomy::StructureSet>(std::move(*set));
  auto in = coverageInputs(shared_set, *robot);
  in.ct = std::make_shared<const volume::Volume>(std::move(*ct));
  auto search = placement::CoverageModel::create(in, search_mm);
  if (!search) return search.error();
  auto final = placement::CoverageModel::create(in, final_mm);
  if (!final) return final.error();
  const Eigen::Matrix4d robot_to_image = rp->image_to_robot_true.inverse();
  placement::RobotPose mounted;
  mounted.origin_lps_mm = robot_to_image.topRightCorner<3, 1>();
  mounted.rotation = robot_to_image.topLeftCorner<3, 3>();
  placement::PlacementLimits limits;
  limits.approach = "superior";  // where the phantom's robot stands
  limits.insertion_lps = *anatomy::insertionFrom(limits.approach);
  return PlacementScene{in.target->name, std::move(*search), std::move(*final), limits, mounted};
}

}  // namespace ignav::test
