// Binary PLY written directly: the format is a text header and packed records, and PCL's
// writer would link VTK into every program that uses the kinematics (+0.3 s start-up, +78 MB).
#include <cstdint>
#include <cstring>
#include <fstream>

#include "ignav/kinematics/workspace_map.hpp"

namespace ignav::kinematics {
namespace {

bool littleEndianHost() {
  const std::uint16_t one = 1;
  unsigned char first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

}  // namespace

Status writeWorkspacePly(const WorkspaceMap& map, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return makeError(ErrorCode::kIo, "cannot write point cloud " + path);
  out << "ply\nformat " << (littleEndianHost() ? "binary_little_endian" : "binary_big_endian")
      << " 1.0\ncomment ignav reachable workspace grid (robot frame, mm); intensity = z_s_mm\n"
      << "element vertex " << map.points_mm.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\nproperty float intensity\n"
      << "end_header\n";
  for (std::size_t i = 0; i < map.points_mm.size(); ++i) {
    const float record[4] = {map.points_mm[i].x(), map.points_mm[i].y(), map.points_mm[i].z(),
                             map.z_s_mm[i]};
    out.write(reinterpret_cast<const char*>(record), sizeof record);
  }
  out.flush();
  if (!out) return makeError(ErrorCode::kIo, "cannot write point cloud " + path);
  return Ok{};
}

}  // namespace ignav::kinematics
