#include "bright_groups.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "ignav/volume/threshold.hpp"

namespace ignav::verification {
namespace {

// 26-connected groups of the bright voxels: union-find over the 13 neighbours that come earlier
// in scan order, each found by a cursor that only moves forward (the neighbour at a fixed offset
// of an increasing index increases). The root of a group is its first voxel; groups are numbered
// in the order of their first voxels. Returns the group of each bright voxel.
std::vector<std::uint32_t> connectedGroups(const std::vector<std::uint32_t>& bright,
                                           const std::array<int, 3>& dims,
                                           std::size_t& group_count) {
  const std::size_t n = bright.size();
  std::vector<std::uint32_t> parent(n);
  for (std::size_t p = 0; p < n; ++p)
    parent[p] = static_cast<std::uint32_t>(p);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  };
  const std::int64_t nx = dims[0], ny = dims[1], nxy = nx * ny;
  struct Offset {
    int di, dj, dk;
    std::int64_t delta;
    std::size_t cursor;
  };
  std::vector<Offset> offsets;
  for (int dk = -1; dk <= 0; ++dk)
    for (int dj = -1; dj <= 1; ++dj)
      for (int di = -1; di <= 1; ++di) {
        const std::int64_t delta = di + dj * nx + dk * nxy;
        if (delta < 0) offsets.push_back({di, dj, dk, delta, 0});
      }
  for (std::size_t p = 0; p < n; ++p) {
    const std::int64_t idx = bright[p];
    const std::int64_t i = idx % nx, j = (idx / nx) % ny, k = idx / nxy;
    for (auto& o : offsets) {
      if (i + o.di < 0 || i + o.di >= nx || j + o.dj < 0 || j + o.dj >= ny || k + o.dk < 0)
        continue;
      const std::int64_t want = idx + o.delta;
      while (o.cursor < p && static_cast<std::int64_t>(bright[o.cursor]) < want)
        ++o.cursor;
      if (o.cursor < p && static_cast<std::int64_t>(bright[o.cursor]) == want) {
        const std::uint32_t a = find(static_cast<std::uint32_t>(p)),
                            b = find(static_cast<std::uint32_t>(o.cursor));
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
    }
  }
  std::vector<std::uint32_t> group(n);
  group_count = 0;
  for (std::size_t p = 0; p < n; ++p) {
    const std::uint32_t root = find(static_cast<std::uint32_t>(p));
    group[p] = root == p ? static_cast<std::uint32_t>(group_count++) : group[root];
  }
  return group;
}

}  // namespace

BrightGroups groupBrightVoxels(std::vector<std::uint32_t> bright, const std::array<int, 3>& dims) {
  BrightGroups out;
  out.dims = dims;
  std::size_t group_count = 0;
  out.group_of = connectedGroups(bright, dims, group_count);
  // Members per group (a counting sort keeps scan order within a group).
  out.start.assign(group_count + 1, 0);
  for (auto grp : out.group_of)
    ++out.start[grp + 1];
  for (std::size_t q = 0; q < group_count; ++q)
    out.start[q + 1] += out.start[q];
  out.members.resize(bright.size());
  std::vector<std::size_t> fill(out.start.begin(), out.start.end() - 1);
  for (std::size_t p = 0; p < bright.size(); ++p)
    out.members[fill[out.group_of[p]]++] = static_cast<std::uint32_t>(p);
  out.bright = std::move(bright);
  return out;
}

Eigen::Vector3i BrightGroups::voxel(std::size_t e) const {
  const std::size_t idx = bright[members[e]];
  const auto nx = static_cast<std::size_t>(dims[0]);
  const std::size_t nxy = nx * static_cast<std::size_t>(dims[1]);
  return {static_cast<int>(idx % nx), static_cast<int>((idx % nxy) / nx),
          static_cast<int>(idx / nxy)};
}

Expected<BrightGroups> findBrightGroups(const volume::Volume& volume, double min_hu,
                                        std::size_t max_bright_voxels, const std::string& search,
                                        const std::string& what) {
  const auto& g = volume.geometry;
  if (auto ok = g.validate("volume"); !ok) return ok.error();
  if (volume.voxels.size() != g.voxelCount()) {
    return makeError(ErrorCode::kInvalidArgument, "volume: voxel buffer does not match its dims");
  }
  auto bright = volume::voxelsAtOrAbove(volume, min_hu, max_bright_voxels);
  if (!bright && bright.error().reason == "too_many_bright_voxels") {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{}: more than {} voxels at or above min_hu {:g} HU; raise "
                                 "min_hu towards {}",
                                 search, max_bright_voxels, min_hu, what));
  }
  if (!bright) return bright.error();
  return groupBrightVoxels(std::move(*bright), g.dims);
}

double medianOf(std::vector<double>& values) {
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

}  // namespace ignav::verification
