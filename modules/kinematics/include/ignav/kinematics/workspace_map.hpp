// The feasible volume sampled on a grid, and its export as a point cloud (PLY) that 3D Slicer
// and ParaView open.
#pragma once

#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/kinematics/solver.hpp"

namespace ignav::kinematics {

// Every grid point (integer multiples of grid_mm in the robot frame) that the instrument reaches,
// with the stylet deployment that reaches it.
struct WorkspaceMap {
  double grid_mm = 0.0;
  std::vector<Eigen::Vector3f> points_mm;
  std::vector<float> z_s_mm;
  // Sampled volume: points × grid³, converges to WorkspaceFigures::volume_exact_cm3.
  double sampledVolume_cm3() const;
};

// grid_mm must be in [0.05, 10]; the error names the value.
Expected<WorkspaceMap> computeWorkspaceMap(const Kinematics& kinematics, double grid_mm);

// Binary little-endian PLY with x, y, z and intensity = z_s (mm).
Status writeWorkspacePly(const WorkspaceMap& map, const std::string& path);

}  // namespace ignav::kinematics
