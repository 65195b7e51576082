// Kept apart: the only translation unit of this module that includes PCL (slow to compile).
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "ignav/kinematics/workspace_map.hpp"

namespace ignav::kinematics {

Status writeWorkspacePly(const WorkspaceMap& map, const std::string& path) {
  pcl::PointCloud<pcl::PointXYZI> cloud;
  cloud.resize(map.points_mm.size());
  for (size_t i = 0; i < map.points_mm.size(); ++i) {
    const Eigen::Vector3f& p = map.points_mm[i];
    cloud[i].x = p.x();
    cloud[i].y = p.y();
    cloud[i].z = p.z();
    cloud[i].intensity = map.z_s_mm[i];
  }
  cloud.width = static_cast<std::uint32_t>(cloud.size());
  cloud.height = 1;
  cloud.is_dense = true;
  if (pcl::io::savePLYFileBinary(path, cloud) != 0) {
    return makeError(ErrorCode::kIo, "cannot write point cloud " + path);
  }
  return Ok{};
}

}  // namespace ignav::kinematics
