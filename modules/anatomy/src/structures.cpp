// Structures, their masks, and whether a segmentation was made on this CT (structures.hpp).
#include "ignav/anatomy/structures.hpp"

#include "ignav/anatomy/dicom_structures.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <numeric>

#include <fmt/format.h>

namespace ignav::anatomy {
namespace fs = std::filesystem;

const char* toString(Role role) {
  switch (role) {
    case Role::kTarget:
      return "target";
    case Role::kAvoid:
      return "avoid";
    case Role::kShown:
      return "shown";
  }
  return "shown";
}

std::optional<Role> roleNamed(std::string_view name) {
  for (const Role r : {Role::kTarget, Role::kAvoid, Role::kShown})
    if (name == toString(r)) return r;
  return std::nullopt;
}

std::size_t Mask::count() const {
  return static_cast<std::size_t>(std::count(inside.begin(), inside.end(), std::uint8_t{1}));
}

double Mask::volume_cm3() const {
  return static_cast<double>(count()) * geometry.spacing_mm.prod() / 1000.0;
}

bool Mask::insideNearest(const Eigen::Vector3d& ijk) const {
  const int i = static_cast<int>(std::lround(ijk.x())), j = static_cast<int>(std::lround(ijk.y())),
            k = static_cast<int>(std::lround(ijk.z()));
  const auto& d = geometry.dims;
  return i >= 0 && j >= 0 && k >= 0 && i < d[0] && j < d[1] && k < d[2] &&
         inside[index(i, j, k)] != 0;
}

std::array<Eigen::Vector3d, 8> Mask::corners(double margin_voxels) const {
  const auto& d = geometry.dims;
  std::array<Eigen::Vector3d, 8> out;
  for (int c = 0; c < 8; ++c) {
    out[static_cast<std::size_t>(c)] =
        geometry.toLps(Eigen::Vector3d((c & 1) ? d[0] - 1 + margin_voxels : -margin_voxels,
                                       (c & 2) ? d[1] - 1 + margin_voxels : -margin_voxels,
                                       (c & 4) ? d[2] - 1 + margin_voxels : -margin_voxels));
  }
  return out;
}

bool namesMatch(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

const Structure* StructureSet::find(std::string_view name) const {
  for (const auto& s : structures)
    if (namesMatch(s.name, name)) return &s;
  return nullptr;
}

Structure* StructureSet::find(std::string_view name) {
  return const_cast<Structure*>(static_cast<const StructureSet*>(this)->find(name));
}

Expected<Mask> cropMask(const volume::Geometry& grid, const std::vector<std::uint8_t>& inside,
                        const std::string& what) {
  const auto& d = grid.dims;
  int lo[3] = {d[0], d[1], d[2]}, hi[3] = {-1, -1, -1};
  std::size_t n = 0;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i, ++n) {
        if (!inside[n]) continue;
        const int at[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::min(lo[a], at[a]);
          hi[a] = std::max(hi[a], at[a]);
        }
      }
  if (hi[0] < 0) {
    return makeError(ErrorCode::kFormat, what + ": the structure is empty (no voxel is set)",
                     "empty_structure");
  }
  Mask mask;
  mask.geometry = grid;
  for (int a = 0; a < 3; ++a)
    mask.geometry.dims[static_cast<std::size_t>(a)] = hi[a] - lo[a] + 1;
  mask.geometry.origin_lps_mm = grid.toLps(Eigen::Vector3d(lo[0], lo[1], lo[2]));
  mask.inside.assign(mask.geometry.voxelCount(), 0);
  const auto& m = mask.geometry.dims;
  for (int k = 0; k < m[2]; ++k)
    for (int j = 0; j < m[1]; ++j)
      for (int i = 0; i < m[0]; ++i) {
        const std::size_t from = gridIndex(d, i + lo[0], j + lo[1], k + lo[2]);
        mask.inside[mask.index(i, j, k)] = inside[from] ? 1 : 0;
      }
  return mask;
}

Expected<StructureSet> readStructures(const std::string& path, const CtFrame& ct) {
  const std::string name = fs::path(path).filename().string();
  auto ends = [&](const char* suffix) {
    const std::string s(suffix);
    return name.size() >= s.size() &&
           namesMatch(std::string_view(name).substr(name.size() - s.size()), s);
  };
  if (ends(".seg.nrrd")) return readSegNrrd(path);
  if (ends(".nrrd") || ends(".nhdr") || ends(".mha") || ends(".mhd")) {
    const fs::path stem = fs::path(path).replace_extension();
    for (const char* ext : {".ctbl", ".txt"}) {
      fs::path table = stem;
      table += ext;
      if (fs::exists(table)) return readLabelMap(path, table.string());
    }
    return makeError(ErrorCode::kIo,
                     fmt::format("{}: a label map needs a colour table naming its labels beside "
                                 "it ({}.ctbl or .txt: lines 'LABEL NAME R G B A')",
                                 path, stem.filename().string()),
                     "names_missing");
  }
  return readDicomStructures(path, ct);
}

Status checkOnCt(const StructureSet& set, const volume::Geometry& ct, const std::string& ct_name) {
  for (const auto& s : set.structures) {
    const auto& g = s.mask.geometry;
    auto refuse = [&](const std::string& how) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("{}: structure '{}' was not made on this CT ({}): {}",
                                   set.source, s.name, ct_name, how),
                       "other_ct");
    };
    for (int a = 0; a < 3; ++a) {
      if (std::abs(g.spacing_mm[a] - ct.spacing_mm[a]) > 1e-3 * ct.spacing_mm[a]) {
        return refuse(
            fmt::format("its voxels measure {:.4g} x {:.4g} x {:.4g} mm, the CT's "
                        "{:.4g} x {:.4g} x {:.4g} mm",
                        g.spacing_mm.x(), g.spacing_mm.y(), g.spacing_mm.z(), ct.spacing_mm.x(),
                        ct.spacing_mm.y(), ct.spacing_mm.z()));
      }
      if ((g.direction.col(a) - ct.direction.col(a)).norm() > 1e-4) {
        return refuse(fmt::format("its axis {} points elsewhere than the CT's", "ijk"[a]));
      }
    }
    const Eigen::Vector3d first = ct.toIjk(g.origin_lps_mm);
    const Eigen::Vector3d off = first - first.array().round().matrix();
    if (off.cwiseAbs().maxCoeff() > 0.01) {
      return refuse(fmt::format("its voxels lie ({:.2f}, {:.2f}, {:.2f}) voxels off the CT's",
                                off.x(), off.y(), off.z()));
    }
    for (int a = 0; a < 3; ++a) {
      const double lo = std::round(first[a]);
      const double hi = lo + g.dims[static_cast<std::size_t>(a)] - 1;
      if (lo < 0 || hi > ct.dims[static_cast<std::size_t>(a)] - 1) {
        return refuse(fmt::format("it reaches voxels {} to {} along {}, the CT has 0 to {}", lo, hi,
                                  "ijk"[a], ct.dims[static_cast<std::size_t>(a)] - 1));
      }
    }
  }
  return Ok{};
}

Expected<StructureSet> voxelise(const volume::Geometry& grid, const Eigen::Matrix4d& lps_to_shape,
                                const std::vector<Shape>& shapes, const std::string& source) {
  StructureSet set;
  set.source = source;
  const Eigen::Matrix4d ijk_to_shape = lps_to_shape * grid.ijkToLps();
  std::vector<std::uint8_t> inside(grid.voxelCount());
  for (const auto& shape : shapes) {
    std::size_t n = 0;
    for (int k = 0; k < grid.dims[2]; ++k)
      for (int j = 0; j < grid.dims[1]; ++j)
        for (int i = 0; i < grid.dims[0]; ++i, ++n)
          inside[n] = shape.sdf((ijk_to_shape * Eigen::Vector4d(i, j, k, 1.0)).head<3>()) <= 0.0;
    auto mask = cropMask(grid, inside, source + ": " + shape.name);
    if (!mask) return mask.error();
    set.structures.push_back(
        {shape.name, shape.colour_rgb, std::move(mask).value(), shape.role, shape.margin_mm});
  }
  return set;
}

}  // namespace ignav::anatomy
