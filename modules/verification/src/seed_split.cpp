#include "seed_split.hpp"

#include <algorithm>
#include <numeric>

namespace ignav::verification {
namespace {

// The group's voxels on a dense box: each cell holds its voxel's index, or −1 outside the group.
struct GroupBox {
  explicit GroupBox(const std::vector<Eigen::Vector3i>& voxels) {
    lo = hi = voxels.front();
    for (const auto& v : voxels) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
    size = hi - lo + Eigen::Vector3i::Ones();
    cell.assign(static_cast<std::size_t>(size.prod()), -1);
    for (std::size_t e = 0; e < voxels.size(); ++e)
      cell[at(voxels[e])] = static_cast<std::int64_t>(e);
  }
  std::size_t at(const Eigen::Vector3i& v) const {
    const Eigen::Vector3i d = v - lo;
    return static_cast<std::size_t>(d.x() + size.x() * (d.y() + size.y() * d.z()));
  }
  // The group's voxels among the 26 neighbours of v.
  template <typename F>
  void forNeighbours(const Eigen::Vector3i& v, F&& f) const {
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const Eigen::Vector3i q = v + Eigen::Vector3i(dx, dy, dz);
          if ((dx | dy | dz) == 0 || (q.array() < lo.array()).any() ||
              (q.array() > hi.array()).any())
            continue;
          if (const std::int64_t e = cell[at(q)]; e >= 0) f(static_cast<std::size_t>(e));
        }
  }
  Eigen::Vector3i lo, hi, size;
  std::vector<std::int64_t> cell;
};

constexpr std::uint32_t kNone = ~std::uint32_t{0};

// The 26-connected components of the voxels at or above `level`: per voxel its component (kNone
// below the level), and each component's peak.
std::vector<std::uint32_t> componentsAbove(const GroupBox& box,
                                           const std::vector<Eigen::Vector3i>& voxels,
                                           const std::vector<double>& values, double level,
                                           std::vector<double>& peaks) {
  std::vector<std::uint32_t> component(voxels.size(), kNone);
  peaks.clear();
  std::vector<std::size_t> stack;
  for (std::size_t seed = 0; seed < voxels.size(); ++seed) {
    if (values[seed] < level || component[seed] != kNone) continue;
    const auto id = static_cast<std::uint32_t>(peaks.size());
    peaks.push_back(values[seed]);
    component[seed] = id;
    stack.assign(1, seed);
    while (!stack.empty()) {
      const std::size_t e = stack.back();
      stack.pop_back();
      box.forNeighbours(voxels[e], [&](std::size_t n) {
        if (values[n] < level || component[n] != kNone) return;
        component[n] = id;
        peaks[id] = std::max(peaks[id], values[n]);
        stack.push_back(n);
      });
    }
  }
  return component;
}

}  // namespace

std::optional<GroupSplit> splitAtValleys(const std::vector<Eigen::Vector3i>& voxels,
                                         const std::vector<double>& values, double min_hu,
                                         double min_depth_hu) {
  if (voxels.size() < 2 || voxels.size() != values.size()) return std::nullopt;
  const GroupBox box(voxels);
  const double peak = *std::max_element(values.begin(), values.end());
  constexpr int kLevels = 20;
  std::vector<double> peaks;
  for (int step = 1; step < kLevels; ++step) {
    const double level = min_hu + (peak - min_hu) * step / kLevels;
    if (peak - level < min_depth_hu) break;  // no core can rise far enough above it any more
    const auto component = componentsAbove(box, voxels, values, level, peaks);
    // The cores: components rising far enough above the level, numbered 0, 1, ...
    std::vector<std::uint32_t> core_of(peaks.size(), kNone);
    std::uint32_t cores = 0;
    for (std::size_t c = 0; c < peaks.size(); ++c)
      if (peaks[c] - level >= min_depth_hu) core_of[c] = cores++;
    if (cores < 2) continue;
    GroupSplit out;
    out.parts = cores;
    out.level_hu = level;
    out.part_of.assign(voxels.size(), kNone);
    for (std::size_t e = 0; e < voxels.size(); ++e)
      if (component[e] != kNone) out.part_of[e] = core_of[component[e]];
    // The rest from the brightest down: each voxel joins the part of its brightest labelled
    // neighbour; passes repeat until every voxel (the group is connected) has one.
    std::vector<std::size_t> order(voxels.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return values[a] > values[b]; });
    for (bool changed = true; changed;) {
      changed = false;
      for (std::size_t e : order) {
        if (out.part_of[e] != kNone) continue;
        double best = -1e300;
        box.forNeighbours(voxels[e], [&](std::size_t n) {
          if (out.part_of[n] != kNone && values[n] > best) {
            best = values[n];
            out.part_of[e] = out.part_of[n];
          }
        });
        changed = changed || out.part_of[e] != kNone;
      }
    }
    // A voxel left without a part (an insignificant core's own group) has none to join: the
    // cores are not all a group's parts then; not split.
    if (std::find(out.part_of.begin(), out.part_of.end(), kNone) != out.part_of.end())
      return std::nullopt;
    return out;
  }
  return std::nullopt;
}

}  // namespace ignav::verification
