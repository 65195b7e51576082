// The 3D view's surfaces (issue 43) against closed forms: a ball's radius and volume, a box's
// faces half a voxel beyond its voxels, a distance field's sphere; each mesh closed (every edge in
// two triangles) and wound outwards, on grids with anisotropic spacing and an oblique direction.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <utility>

#include "ignav/surfaces/surfaces.hpp"

namespace ignav::surfaces {
namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Vector3d vertex(const TriangleMesh& m, std::uint32_t i) {
  return {m.points_lps[3 * i], m.points_lps[3 * i + 1], m.points_lps[3 * i + 2]};
}

// The enclosed volume by the divergence theorem: positive when the triangles face outwards.
double enclosedVolume_mm3(const TriangleMesh& m) {
  double six = 0.0;
  for (std::size_t t = 0; t < m.triangles.size(); t += 3) {
    six += vertex(m, m.triangles[t])
               .dot(vertex(m, m.triangles[t + 1]).cross(vertex(m, m.triangles[t + 2])));
  }
  return six / 6.0;
}

// Closed and consistently wound: every directed edge once, its reverse once.
void expectClosed(const TriangleMesh& m) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
  for (std::size_t t = 0; t < m.triangles.size(); t += 3) {
    for (int e = 0; e < 3; ++e)
      ++directed[{m.triangles[t + e], m.triangles[t + (e + 1) % 3]}];
  }
  int unpaired = 0, repeated = 0;
  for (const auto& [edge, n] : directed) {
    if (n != 1) ++repeated;
    if (directed.count({edge.second, edge.first}) == 0) ++unpaired;
  }
  EXPECT_EQ(unpaired, 0) << "edges on a hole";
  EXPECT_EQ(repeated, 0) << "edges wound twice the same way";
}

// An oblique grid: spacing 0.8 x 0.9 x 1.5 mm, rotated 30 degrees about (1, 2, 3), centred on c.
volume::Geometry obliqueGrid(const std::array<int, 3>& dims, const Eigen::Vector3d& c) {
  volume::Geometry g;
  g.dims = dims;
  g.spacing_mm = {0.8, 0.9, 1.5};
  g.direction = Eigen::AngleAxisd(kPi / 6, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  const Eigen::Vector3d half((dims[0] - 1) / 2.0, (dims[1] - 1) / 2.0, (dims[2] - 1) / 2.0);
  g.origin_lps_mm = c - g.direction * g.spacing_mm.cwiseProduct(half);
  return g;
}

template <typename F>
auto sampled(const volume::Geometry& g, F f) {
  std::vector<decltype(f(Eigen::Vector3d()))> out;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        out.push_back(f(g.toLps(Eigen::Vector3d(i, j, k))));
  return out;
}

TEST(MaskSurface, BallOnAnObliqueGridHasItsRadiusAndVolume) {
  const Eigen::Vector3d c(12.0, -30.0, 55.0);
  const double r = 10.0;
  const auto g = obliqueGrid({34, 30, 20}, c);
  const auto inside = sampled(g, [&](const Eigen::Vector3d& p) {
    return static_cast<std::uint8_t>((p - c).norm() <= r ? 1 : 0);
  });
  const auto mesh = maskSurface(g, inside, "ball");
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  ASSERT_GT(mesh->triangleCount(), 500u);
  expectClosed(*mesh);
  // Within half the coarsest voxel of the sphere: the mask's boundary is voxel-steps smoothed.
  for (std::uint32_t i = 0; i < mesh->vertexCount(); ++i)
    EXPECT_NEAR((vertex(*mesh, i) - c).norm(), r, 0.75) << "vertex " << i;
  EXPECT_NEAR(enclosedVolume_mm3(*mesh), 4.0 / 3.0 * kPi * r * r * r, 0.05 * 4188.79);
}

TEST(MaskSurface, UnsmoothedBoxReachesHalfAVoxelBeyondItsVoxelsOnEveryFace) {
  volume::Geometry g = obliqueGrid({12, 10, 9}, Eigen::Vector3d(0, 0, 0));
  // The mask fills i 0..5 (touching the grid's face), j 2..7, k 3..8 (touching the last face).
  std::vector<std::uint8_t> inside(g.voxelCount(), 0);
  for (int k = 3; k <= 8; ++k)
    for (int j = 2; j <= 7; ++j)
      for (int i = 0; i <= 5; ++i)
        inside[static_cast<std::size_t>(i + 12 * (j + 10 * k))] = 1;
  SurfaceOptions raw;
  raw.smoothing_iterations = 0;
  const auto mesh = maskSurface(g, inside, "box", raw);
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  expectClosed(*mesh);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (std::uint32_t v = 0; v < mesh->vertexCount(); ++v) {
    const Eigen::Vector3d ijk = g.toIjk(vertex(*mesh, v));
    lo = lo.cwiseMin(ijk);
    hi = hi.cwiseMax(ijk);
  }
  EXPECT_NEAR(lo.x(), -0.5, 1e-4);
  EXPECT_NEAR(hi.x(), 5.5, 1e-4);
  EXPECT_NEAR(lo.y(), 1.5, 1e-4);
  EXPECT_NEAR(hi.y(), 7.5, 1e-4);
  EXPECT_NEAR(lo.z(), 2.5, 1e-4);
  EXPECT_NEAR(hi.z(), 8.5, 1e-4);
  // Its corners and edges are cut (marching cubes), never widened: at most the voxels' volume.
  const double voxels_mm3 = 6 * 6 * 6 * 0.8 * 0.9 * 1.5;
  EXPECT_GT(enclosedVolume_mm3(*mesh), 0.8 * voxels_mm3);
  EXPECT_LE(enclosedVolume_mm3(*mesh), voxels_mm3 + 1e-6);
}

TEST(IsoSurface, DistanceFieldSphereLiesOnItsRadius) {
  const Eigen::Vector3d c(-4.0, 7.0, 20.0);
  const double r = 9.0;
  const auto g = obliqueGrid({30, 28, 18}, c);
  const auto field =
      sampled(g, [&](const Eigen::Vector3d& p) { return static_cast<float>(r - (p - c).norm()); });
  const auto mesh = isoSurface(g, field, 0.0, "sphere");
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  ASSERT_GT(mesh->triangleCount(), 500u);
  expectClosed(*mesh);
  // Linear interpolation of a distance along a voxel's edge: off by at most h^2 / (2 r).
  for (std::uint32_t i = 0; i < mesh->vertexCount(); ++i)
    EXPECT_NEAR((vertex(*mesh, i) - c).norm(), r, 1.5 * 1.5 / (2 * r)) << "vertex " << i;
  EXPECT_NEAR(enclosedVolume_mm3(*mesh), 4.0 / 3.0 * kPi * r * r * r, 0.02 * 3053.6);
}

TEST(IsoSurface, FieldCutByTheGridIsClosedOnItsFaces) {
  const auto g = obliqueGrid({10, 10, 10}, Eigen::Vector3d(0, 0, 0));
  const std::vector<float> field(g.voxelCount(), 5.0f);  // at or above the level everywhere
  const auto mesh = isoSurface(g, field, 2.0, "everywhere");
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  expectClosed(*mesh);
  // Beyond the grid the field is its lowest value (here the level, 2) less max(1, |level|): 0.
  // The surface crosses between the last voxel centres (5) and that padding at (5 - 2) / (5 - 0)
  // of a voxel beyond them.
  const double lo = -0.6, hi = 9.6;
  Eigen::Vector3d mn = Eigen::Vector3d::Constant(1e9), mx = -mn;
  for (std::uint32_t v = 0; v < mesh->vertexCount(); ++v) {
    const Eigen::Vector3d ijk = g.toIjk(vertex(*mesh, v));
    mn = mn.cwiseMin(ijk);
    mx = mx.cwiseMax(ijk);
  }
  EXPECT_NEAR(mn.minCoeff(), lo, 1e-4);
  EXPECT_NEAR(mx.maxCoeff(), hi, 1e-4);
}

TEST(IsoSurface, NothingAtTheLevelIsAnEmptyMesh) {
  const auto g = obliqueGrid({6, 6, 6}, Eigen::Vector3d(0, 0, 0));
  const auto mesh = isoSurface(g, std::vector<float>(g.voxelCount(), 1.0f), 3.0, "cold");
  ASSERT_TRUE(mesh.ok());
  EXPECT_EQ(mesh->triangleCount(), 0u);
}

TEST(Surfaces, BadInputIsRefusedNamingWhat) {
  const auto g = obliqueGrid({6, 6, 6}, Eigen::Vector3d(0, 0, 0));
  const auto empty = maskSurface(g, std::vector<std::uint8_t>(g.voxelCount(), 0), "urethra");
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error().message.find("urethra"), std::string::npos) << empty.error().message;
  const auto short_mask = maskSurface(g, std::vector<std::uint8_t>(10, 1), "rectum");
  ASSERT_FALSE(short_mask.ok());
  EXPECT_NE(short_mask.error().message.find("rectum: 10 values"), std::string::npos);
  std::vector<float> field(g.voxelCount(), 1.0f);
  field[7] = std::nanf("");
  const auto nan = isoSurface(g, field, 0.5, "dose");
  ASSERT_FALSE(nan.ok());
  EXPECT_NE(nan.error().message.find("dose"), std::string::npos);
  EXPECT_FALSE(isoSurface(g, std::vector<float>(g.voxelCount(), 1.0f), NAN, "dose").ok());
}

}  // namespace
}  // namespace ignav::surfaces
