// The dose as NRRD (dose_nrrd.hpp): one file, the header then raw little-endian floats.
#include "ignav/dosimetry/dose_nrrd.hpp"

#include <cmath>
#include <fstream>

#include <fmt/format.h>

namespace ignav::dosimetry {

Status writeDoseNrrd(const std::vector<float>& dose_Gy, const volume::Geometry& grid,
                     const std::string& path) {
  if (dose_Gy.size() != grid.voxelCount())
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{}: {} dose values for a grid of {} voxels", path, dose_Gy.size(),
                                 grid.voxelCount()),
                     "bad_dose");
  for (std::size_t i = 0; i < dose_Gy.size(); ++i)
    if (!std::isfinite(dose_Gy[i]) || dose_Gy[i] < 0.0f)
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("{}: voxel {}'s dose {} Gy is not a dose", path, i, dose_Gy[i]),
                       "bad_dose");
  std::ofstream out(path, std::ios::binary);
  if (!out) return makeError(ErrorCode::kIo, "cannot write " + path);
  // Space directions are the grid's columns scaled by its spacing (NRRD's convention).
  std::string directions;
  for (int c = 0; c < 3; ++c) {
    const Eigen::Vector3d v = grid.direction.col(c) * grid.spacing_mm[c];
    directions += fmt::format("{}({:.17g},{:.17g},{:.17g})", c ? " " : "", v.x(), v.y(), v.z());
  }
  const auto& o = grid.origin_lps_mm;
  out << "NRRD0004\n"
      << "# the dose of ignav's seeds (Gy), on the dose grid\n"
      << "type: float\ndimension: 3\nspace: left-posterior-superior\n"
      << fmt::format("sizes: {} {} {}\n", grid.dims[0], grid.dims[1], grid.dims[2])
      << "space directions: " << directions << "\n"
      << "kinds: domain domain domain\nendian: little\nencoding: raw\n"
      << fmt::format("space origin: ({:.17g},{:.17g},{:.17g})\n", o.x(), o.y(), o.z())
      << "space units: \"mm\" \"mm\" \"mm\"\n"
      << "units:=Gy\n\n";
  static_assert(sizeof(float) == 4, "NRRD float is 32-bit");
  // x86-64 and aarch64 are little-endian, as the header says.
  out.write(reinterpret_cast<const char*>(dose_Gy.data()),
            static_cast<std::streamsize>(dose_Gy.size() * sizeof(float)));
  out.close();
  if (!out) return makeError(ErrorCode::kIo, "could not finish writing " + path);
  return Ok{};
}

}  // namespace ignav::dosimetry
