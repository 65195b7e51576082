// Signed distance fields (distance_field.hpp). The mask's transform keeps, for every voxel, the
// nearest voxel of the other kind (a feature-propagating Felzenszwalb-Huttenlocher transform), so
// the distance can be taken to that voxel's cube rather than its centre: exact for the staircase
// surface the mask draws, with thick slices as well as thin ones.
#include "ignav/anatomy/distance_field.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

namespace ignav::anatomy {
namespace {

constexpr float kFar = std::numeric_limits<float>::infinity();

// Scratch for one line of the transform.
struct Line {
  std::vector<float> f;
  std::vector<std::int32_t> feature;
  std::vector<int> v;
  std::vector<float> z;
  void resize(int n) {
    f.resize(static_cast<std::size_t>(n));
    feature.resize(static_cast<std::size_t>(n));
    v.resize(static_cast<std::size_t>(n));
    z.resize(static_cast<std::size_t>(n) + 1);
  }
};

// One line of the transform (Felzenszwalb & Huttenlocher): d[q] = min over sites p of
// (x_q - x_p)² + f[p], the site's feature carried along. A line without a site stays as it is.
void transformLine(float* f, std::int32_t* feature, std::size_t stride, int n, float spacing,
                   Line& line) {
  for (int q = 0; q < n; ++q) {
    line.f[static_cast<std::size_t>(q)] = f[stride * static_cast<std::size_t>(q)];
    line.feature[static_cast<std::size_t>(q)] = feature[stride * static_cast<std::size_t>(q)];
  }
  int k = -1;
  for (int q = 0; q < n; ++q) {
    const float fq = line.f[static_cast<std::size_t>(q)];
    if (fq == kFar) continue;
    const float xq = static_cast<float>(q) * spacing;
    float s = -kFar;
    while (k >= 0) {
      const int p = line.v[static_cast<std::size_t>(k)];
      const float xp = static_cast<float>(p) * spacing;
      s = ((fq + xq * xq) - (line.f[static_cast<std::size_t>(p)] + xp * xp)) / (2.0f * (xq - xp));
      if (s > line.z[static_cast<std::size_t>(k)]) break;
      --k;
    }
    ++k;
    line.v[static_cast<std::size_t>(k)] = q;
    line.z[static_cast<std::size_t>(k)] = k == 0 ? -kFar : s;
    line.z[static_cast<std::size_t>(k) + 1] = kFar;
  }
  if (k < 0) return;
  int j = 0;
  for (int q = 0; q < n; ++q) {
    const float xq = static_cast<float>(q) * spacing;
    while (line.z[static_cast<std::size_t>(j) + 1] < xq)
      ++j;
    const int p = line.v[static_cast<std::size_t>(j)];
    const float dx = xq - static_cast<float>(p) * spacing;
    f[stride * static_cast<std::size_t>(q)] = dx * dx + line.f[static_cast<std::size_t>(p)];
    feature[stride * static_cast<std::size_t>(q)] = line.feature[static_cast<std::size_t>(p)];
  }
}

// Within the box [lo, lo + n) of a grid of `dims` voxels: for every voxel, the nearest voxel
// (its index in the grid) whose `inside` equals `of`; -1 where the box holds none. Indices are
// the box's, i fastest.
std::vector<std::int32_t> nearestOf(const std::array<int, 3>& dims, const Eigen::Vector3d& spacing,
                                    const std::vector<std::uint8_t>& inside, std::uint8_t of,
                                    const Eigen::Array3i& lo, const Eigen::Array3i& n) {
  const std::size_t nx = static_cast<std::size_t>(n[0]), ny = static_cast<std::size_t>(n[1]);
  const std::size_t count = nx * ny * static_cast<std::size_t>(n[2]);
  std::vector<float> f(count, kFar);
  std::vector<std::int32_t> feature(count, -1);
  // Along i: the nearest site of each row directly, by two sweeps.
  const float hx = static_cast<float>(spacing.x());
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j) {
      const std::size_t row = nx * (static_cast<std::size_t>(j) + ny * k);
      const std::size_t grid_row = gridIndex(dims, lo[0], j + lo[1], k + lo[2]);
      int last = -1;
      for (int i = 0; i < n[0]; ++i) {
        if (inside[grid_row + static_cast<std::size_t>(i)] == of) last = i;
        if (last >= 0) {
          const float d = static_cast<float>(i - last) * hx;
          f[row + static_cast<std::size_t>(i)] = d * d;
          feature[row + static_cast<std::size_t>(i)] =
              static_cast<std::int32_t>(grid_row + static_cast<std::size_t>(last));
        }
      }
      last = -1;
      for (int i = n[0] - 1; i >= 0; --i) {
        if (inside[grid_row + static_cast<std::size_t>(i)] == of) last = i;
        if (last >= 0) {
          const float d = static_cast<float>(last - i) * hx;
          if (d * d < f[row + static_cast<std::size_t>(i)]) {
            f[row + static_cast<std::size_t>(i)] = d * d;
            feature[row + static_cast<std::size_t>(i)] =
                static_cast<std::int32_t>(grid_row + static_cast<std::size_t>(last));
          }
        }
      }
    }
  Line line;
  line.resize(std::max(n[1], n[2]));
  for (int k = 0; k < n[2]; ++k)
    for (int i = 0; i < n[0]; ++i) {
      const std::size_t at = static_cast<std::size_t>(i) + nx * ny * k;
      transformLine(f.data() + at, feature.data() + at, nx, n[1], static_cast<float>(spacing.y()),
                    line);
    }
  for (int j = 0; j < n[1]; ++j)
    for (int i = 0; i < n[0]; ++i) {
      const std::size_t at = static_cast<std::size_t>(i) + nx * j;
      transformLine(f.data() + at, feature.data() + at, nx * ny, n[2],
                    static_cast<float>(spacing.z()), line);
    }
  return feature;
}

// Voxels of `g` split into pieces of at most kFieldSpacing_mm along each axis.
Eigen::Array3i subdivisions(const volume::Geometry& g) {
  Eigen::Array3i s;
  for (int a = 0; a < 3; ++a)
    s[a] = std::max(1, static_cast<int>(std::ceil(g.spacing_mm[a] / kFieldSpacing_mm - 1e-9)));
  return s;
}

// The same mask on voxels split by `s`: the union of its cubes is unchanged.
Mask subdivide(const Mask& coarse, const Eigen::Array3i& s) {
  if ((s == 1).all()) return coarse;
  const auto& c = coarse.geometry;
  Mask fine;
  auto& f = fine.geometry;
  f = c;
  for (int a = 0; a < 3; ++a) {
    f.dims[static_cast<std::size_t>(a)] = c.dims[static_cast<std::size_t>(a)] * s[a];
    f.spacing_mm[a] = c.spacing_mm[a] / s[a];
  }
  // The first fine voxel's centre: the coarse one's less half a coarse voxel, plus half a fine.
  f.origin_lps_mm = c.origin_lps_mm +
                    c.direction * (0.5 * (f.spacing_mm.array() - c.spacing_mm.array())).matrix();
  fine.inside.resize(f.voxelCount());
  std::size_t n = 0;
  for (int k = 0; k < f.dims[2]; ++k)
    for (int j = 0; j < f.dims[1]; ++j)
      for (int i = 0; i < f.dims[0]; ++i)
        fine.inside[n++] = coarse.inside[coarse.index(i / s[0], j / s[1], k / s[2])];
  return fine;
}

}  // namespace

DistanceField DistanceField::fromMask(const Mask& coarse, double reach_mm) {
  const Mask mask = subdivide(coarse, subdivisions(coarse.geometry));
  const auto& m = mask.geometry;
  DistanceField out;
  out.grid_ = m;
  Eigen::Array3i pad;
  double reach = kFar;
  for (int a = 0; a < 3; ++a) {
    const double h = m.spacing_mm[a];
    pad[a] = std::max(1, static_cast<int>(std::ceil(std::max(reach_mm, 0.0) / h + 0.5)));
    out.grid_.dims[static_cast<std::size_t>(a)] = m.dims[static_cast<std::size_t>(a)] + 2 * pad[a];
    reach = std::min(reach, pad[a] * h - 0.5 * h);  // the box's gap to the outermost cubes
  }
  out.reach_mm_ = reach;
  out.grid_.origin_lps_mm = m.toLps(Eigen::Vector3d(-pad[0], -pad[1], -pad[2]));
  const auto& g = out.grid_;
  std::vector<std::uint8_t> inside(g.voxelCount(), 0);
  for (int k = 0; k < m.dims[2]; ++k)
    for (int j = 0; j < m.dims[1]; ++j)
      for (int i = 0; i < m.dims[0]; ++i)
        inside[gridIndex(g.dims, i + pad[0], j + pad[1], k + pad[2])] =
            mask.inside[mask.index(i, j, k)];
  // Outside voxels: their nearest inside voxel, over the whole box. Inside voxels: their
  // nearest outside one, found within the mask's box and the ring of outside voxels around it
  // (any outside voxel beyond that ring has a ring voxel at least as near).
  const Eigen::Array3i all = Eigen::Array3i(g.dims[0], g.dims[1], g.dims[2]);
  const Eigen::Array3i ring_lo = pad - 1;
  const Eigen::Array3i ring_n = Eigen::Array3i(m.dims[0], m.dims[1], m.dims[2]) + 2;
  const auto to_inside = nearestOf(g.dims, g.spacing_mm, inside, 1, Eigen::Array3i::Zero(), all);
  const auto to_outside = nearestOf(g.dims, g.spacing_mm, inside, 0, ring_lo, ring_n);
  const std::size_t nx = static_cast<std::size_t>(g.dims[0]);
  const std::size_t nxy = nx * static_cast<std::size_t>(g.dims[1]);
  const Eigen::Array3d h = g.spacing_mm.array();
  out.values_.resize(g.voxelCount());
  std::size_t n = 0;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i, ++n) {
        const bool in = inside[n] != 0;
        std::int32_t other = 0;
        if (in) {
          const Eigen::Array3i r = Eigen::Array3i(i, j, k) - ring_lo;
          other = to_outside[gridIndex({ring_n[0], ring_n[1], ring_n[2]}, r[0], r[1], r[2])];
        } else {
          other = to_inside[n];
        }
        const auto o = static_cast<std::size_t>(other);
        // From this voxel's centre to the other kind's nearest voxel's cube.
        const Eigen::Array3d offset =
            (Eigen::Array3d(i, j, k) - Eigen::Array3d(static_cast<double>(o % nx),
                                                      static_cast<double>((o % nxy) / nx),
                                                      static_cast<double>(o / nxy)))
                    .abs() *
                h -
            0.5 * h;
        const double distance = offset.max(0.0).matrix().norm();
        out.values_[n] = static_cast<float>(in ? -distance : distance);
      }
  out.lps_to_ijk_ = g.lpsToIjk();
  return out;
}

DistanceField DistanceField::fromFunction(
    const volume::Geometry& coarse, const std::function<double(const Eigen::Vector3d&)>& sdf_lps,
    double reach_mm) {
  const Eigen::Array3i s = subdivisions(coarse);
  volume::Geometry grid = coarse;
  for (int a = 0; a < 3; ++a) {
    grid.dims[static_cast<std::size_t>(a)] =
        (coarse.dims[static_cast<std::size_t>(a)] - 1) * s[a] + 1;
    grid.spacing_mm[a] = coarse.spacing_mm[a] / s[a];
  }
  DistanceField out;
  out.grid_ = grid;
  out.reach_mm_ = reach_mm;
  out.lps_to_ijk_ = grid.lpsToIjk();
  out.values_.resize(grid.voxelCount());
  std::size_t n = 0;
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i)
        out.values_[n++] = static_cast<float>(sdf_lps(grid.toLps(Eigen::Vector3d(i, j, k))));
  return out;
}

double DistanceField::atIjk(const Eigen::Vector3d& ijk) const {
  const auto& d = grid_.dims;
  double beyond_sq = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double hi = d[static_cast<std::size_t>(a)] - 1;
    const double excess = ijk[a] < 0.0 ? -ijk[a] : (ijk[a] > hi ? ijk[a] - hi : 0.0);
    beyond_sq += std::pow(excess * grid_.spacing_mm[a], 2);
  }
  if (beyond_sq > 0.0) return std::sqrt(beyond_sq) + reach_mm_;
  int base[3];
  double w[3];
  for (int a = 0; a < 3; ++a) {
    const int hi = d[static_cast<std::size_t>(a)] - 1;
    base[a] = std::min(static_cast<int>(std::floor(ijk[a])), std::max(hi - 1, 0));
    w[a] = hi == 0 ? 0.0 : ijk[a] - base[a];
  }
  const std::size_t nx = static_cast<std::size_t>(d[0]);
  const std::size_t nxy = nx * static_cast<std::size_t>(d[1]);
  const std::size_t step[3] = {d[0] > 1 ? 1u : 0u, d[1] > 1 ? nx : 0u, d[2] > 1 ? nxy : 0u};
  const std::size_t at0 = static_cast<std::size_t>(base[0]) +
                          nx * static_cast<std::size_t>(base[1]) +
                          nxy * static_cast<std::size_t>(base[2]);
  double sum = 0.0;
  for (int c = 0; c < 8; ++c) {
    const int bx = c & 1, by = (c >> 1) & 1, bz = (c >> 2) & 1;
    const double weight = (bx ? w[0] : 1 - w[0]) * (by ? w[1] : 1 - w[1]) * (bz ? w[2] : 1 - w[2]);
    if (weight == 0.0) continue;
    sum += weight * values_[at0 + bx * step[0] + by * step[1] + bz * step[2]];
  }
  return sum;
}

double DistanceField::at(const Eigen::Vector3d& lps_mm) const {
  return atIjk((lps_to_ijk_ * lps_mm.homogeneous()).head<3>());
}

Eigen::Vector3d DistanceField::gradient(const Eigen::Vector3d& lps_mm) const {
  const double h = 0.5 * grid_.spacing_mm.minCoeff();
  Eigen::Vector3d g;
  for (int a = 0; a < 3; ++a) {
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(a) * h;
    g[a] = (at(lps_mm + e) - at(lps_mm - e)) / (2.0 * h);
  }
  const double norm = g.norm();
  return norm > 1e-9 ? Eigen::Vector3d(g / norm) : Eigen::Vector3d::Zero();
}

}  // namespace ignav::anatomy
