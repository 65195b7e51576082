// The signed distance to one structure's surface (mm, negative inside), on a box of voxels that
// reaches a given distance around it: what a needle's clearance is measured with (clearance.hpp).
#pragma once

#include <functional>
#include <vector>

#include <Eigen/Core>

#include "ignav/anatomy/structures.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::anatomy {

// A field's voxels measure at most this along each axis, whatever the CT's: trilinear
// interpolation of a distance then errs by about 0.03 mm beside a 2 mm-radius cylinder (the
// error grows as spacing² / distance from its axis; at a CT's 2 mm it is 0.1-0.2 mm). A mask
// itself is known to half its voxel, which dwarfs that: a CT's 0.8 mm pixels and 1 mm slices are
// kept, its 1.25 mm slices halved.
constexpr double kFieldSpacing_mm = 1.0;

class DistanceField {
 public:
  // From a mask: the exact distance to the surface its voxels' cubes draw (a Felzenszwalb &
  // Huttenlocher transform that keeps each voxel's nearest voxel of the other kind), the voxels
  // split to kFieldSpacing_mm first. As accurate as the mask: half a voxel at worst where the
  // true surface is curved, exact where it follows the voxels. The box reaches at least
  // `reach_mm` beyond the mask.
  static DistanceField fromMask(const Mask& mask, double reach_mm);
  // A signed distance function (closed forms: tests, the built-in phantom's anatomy) sampled on
  // `grid`, its voxels split to kFieldSpacing_mm; `reach_mm` is how far the shape lies inside
  // the grid's box at least.
  static DistanceField fromFunction(const volume::Geometry& grid,
                                    const std::function<double(const Eigen::Vector3d&)>& sdf_lps,
                                    double reach_mm);

  // Trilinear within the box; beyond it a lower bound (the distance to the box plus the reach),
  // which is all a clearance needs of tissue that far away.
  double at(const Eigen::Vector3d& lps_mm) const;
  // The direction of increasing distance (unit; zero where flat), by central differences.
  Eigen::Vector3d gradient(const Eigen::Vector3d& lps_mm) const;
  double reach_mm() const { return reach_mm_; }
  const volume::Geometry& grid() const { return grid_; }
  std::size_t bytes() const { return values_.size() * sizeof(float); }

 private:
  double atIjk(const Eigen::Vector3d& ijk) const;
  volume::Geometry grid_;
  Eigen::Matrix4d lps_to_ijk_ = Eigen::Matrix4d::Identity();
  std::vector<float> values_;
  double reach_mm_ = 0.0;
};

}  // namespace ignav::anatomy
