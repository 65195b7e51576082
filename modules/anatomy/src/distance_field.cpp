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

constexpr double kFar = std::numeric_limits<double>::infinity();

// One line of the transform: d[q] = min over sites v of (x_q - x_v)² + f[v], with the site's
// feature carried along. Lines without a site stay as they are (kFar, -1).
void transformLine(std::vector<double>& f, std::vector<std::int64_t>& feature, std::size_t start,
                   std::size_t stride, int n, double spacing, std::vector<int>& v,
                   std::vector<double>& z, std::vector<double>& line_f,
                   std::vector<std::int64_t>& line_feature) {
  line_f.resize(static_cast<std::size_t>(n));
  line_feature.resize(static_cast<std::size_t>(n));
  for (int q = 0; q < n; ++q) {
    line_f[static_cast<std::size_t>(q)] = f[start + stride * static_cast<std::size_t>(q)];
    line_feature[static_cast<std::size_t>(q)] =
        feature[start + stride * static_cast<std::size_t>(q)];
  }
  v.resize(static_cast<std::size_t>(n));
  z.resize(static_cast<std::size_t>(n) + 1);
  int k = -1;
  for (int q = 0; q < n; ++q) {
    const double fq = line_f[static_cast<std::size_t>(q)];
    if (!std::isfinite(fq)) continue;
    const double xq = q * spacing;
    double s = -kFar;
    while (k >= 0) {
      const int p = v[static_cast<std::size_t>(k)];
      const double xp = p * spacing;
      s = ((fq + xq * xq) - (line_f[static_cast<std::size_t>(p)] + xp * xp)) / (2.0 * (xq - xp));
      if (s > z[static_cast<std::size_t>(k)]) break;
      --k;
    }
    ++k;
    v[static_cast<std::size_t>(k)] = q;
    z[static_cast<std::size_t>(k)] = k == 0 ? -kFar : s;
    z[static_cast<std::size_t>(k) + 1] = kFar;
  }
  if (k < 0) return;
  int j = 0;
  for (int q = 0; q < n; ++q) {
    const double xq = q * spacing;
    while (z[static_cast<std::size_t>(j) + 1] < xq)
      ++j;
    const int p = v[static_cast<std::size_t>(j)];
    const double dx = xq - p * spacing;
    const std::size_t at = start + stride * static_cast<std::size_t>(q);
    f[at] = dx * dx + line_f[static_cast<std::size_t>(p)];
    feature[at] = line_feature[static_cast<std::size_t>(p)];
  }
}

// For every voxel of `grid`, the nearest voxel (linear index) whose `inside` equals `of`.
std::vector<std::int64_t> nearestOf(const volume::Geometry& grid,
                                    const std::vector<std::uint8_t>& inside, std::uint8_t of) {
  const auto& d = grid.dims;
  const std::size_t n = grid.voxelCount();
  std::vector<double> f(n, kFar);
  std::vector<std::int64_t> feature(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    if (inside[i] == of) {
      f[i] = 0.0;
      feature[i] = static_cast<std::int64_t>(i);
    }
  }
  std::vector<int> v;
  std::vector<double> z, line_f;
  std::vector<std::int64_t> line_feature;
  const std::size_t nx = static_cast<std::size_t>(d[0]), ny = static_cast<std::size_t>(d[1]);
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      transformLine(f, feature, nx * (static_cast<std::size_t>(j) + ny * k), 1, d[0],
                    grid.spacing_mm.x(), v, z, line_f, line_feature);
  for (int k = 0; k < d[2]; ++k)
    for (int i = 0; i < d[0]; ++i)
      transformLine(f, feature, static_cast<std::size_t>(i) + nx * ny * k, nx, d[1],
                    grid.spacing_mm.y(), v, z, line_f, line_feature);
  for (int j = 0; j < d[1]; ++j)
    for (int i = 0; i < d[0]; ++i)
      transformLine(f, feature, static_cast<std::size_t>(i) + nx * j, nx * ny, d[2],
                    grid.spacing_mm.z(), v, z, line_f, line_feature);
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
  int pad[3];
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
        inside[static_cast<std::size_t>(i + pad[0]) +
               static_cast<std::size_t>(g.dims[0]) *
                   (static_cast<std::size_t>(j + pad[1]) +
                    static_cast<std::size_t>(g.dims[1]) * static_cast<std::size_t>(k + pad[2]))] =
            mask.inside[mask.index(i, j, k)];
  const auto to_inside = nearestOf(g, inside, 1);
  const auto to_outside = nearestOf(g, inside, 0);
  const std::size_t nx = static_cast<std::size_t>(g.dims[0]);
  const std::size_t nxy = nx * static_cast<std::size_t>(g.dims[1]);
  const Eigen::Array3d half = 0.5 * g.spacing_mm.array();
  out.values_.resize(g.voxelCount());
  for (std::size_t n = 0; n < out.values_.size(); ++n) {
    const bool in = inside[n] != 0;
    const std::int64_t other = in ? to_outside[n] : to_inside[n];
    // Distance from this voxel's centre to the other kind's nearest voxel's cube.
    const auto ijk = [&](std::size_t x) {
      return Eigen::Array3d(static_cast<double>(x % nx), static_cast<double>((x % nxy) / nx),
                            static_cast<double>(x / nxy));
    };
    const Eigen::Array3d offset =
        (ijk(n) - ijk(static_cast<std::size_t>(other))).abs() * g.spacing_mm.array() - half;
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
