// The whole needle's clearance against closed forms (issue 41): a straight segment past a
// sphere, an arc past a cylinder, a segment past a box whose voxels are exact; each at several
// voxel sizes, within 0.1 mm.
#include <gtest/gtest.h>

#include <cmath>

#include <Eigen/Geometry>

#include "ignav/anatomy/clearance.hpp"

namespace ignav::anatomy {
namespace {

volume::Geometry gridAround(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                            const Eigen::Vector3d& spacing) {
  volume::Geometry g;
  g.spacing_mm = spacing;
  g.origin_lps_mm = lo;
  for (int a = 0; a < 3; ++a)
    g.dims[static_cast<std::size_t>(a)] =
        static_cast<int>(std::ceil((hi[a] - lo[a]) / spacing[a])) + 1;
  return g;
}

std::vector<Eigen::Vector3d> segment(const Eigen::Vector3d& a, const Eigen::Vector3d& b, int n) {
  std::vector<Eigen::Vector3d> out;
  for (int i = 0; i <= n; ++i)
    out.push_back(a + (b - a) * (static_cast<double>(i) / n));
  return out;
}

double distanceToSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                         const Eigen::Vector3d& b) {
  const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
  return (a + t * (b - a) - p).norm();
}

TEST(Clearance, AStraightSegmentPastASphereMatchesTheClosedFormAtEveryVoxelSize) {
  const Eigen::Vector3d centre(3.3, -2.1, 10.7);
  const double radius = 6.0, needle_radius = 0.6;
  const auto sphere = [&](const Eigen::Vector3d& p) { return (p - centre).norm() - radius; };
  const Eigen::Vector3d lo = centre.array() - 30.0, hi = centre.array() + 30.0;
  for (const double h : {0.5, 1.0, 2.0}) {
    const auto field =
        DistanceField::fromFunction(gridAround(lo, hi, Eigen::Vector3d::Constant(h)), sphere, 20.0);
    // Segments passing at several distances, one ending short of the sphere, one through it.
    const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> cases = {
        {{-20, 5.0, 0}, {25, 4.0, 20}},    {{-10, -15, 10}, {20, 10, 12}},
        {{3.3, -2.1, -15}, {3.3, 9.0, 3}}, {{-20, -2.1, 10.7}, {-5, -2.1, 10.7}},
        {{-20, -2, 10}, {20, -2.5, 11}},
    };
    for (const auto& [a, b] : cases) {
      const NeedleBody body = {{segment(a, b, 7), needle_radius}};
      const auto found = closestApproach(body, field, 0.1);
      const double expected = distanceToSegment(centre, a, b) - radius - needle_radius;
      // Where the needle enters, its depth is known to the field's resolution: the distance
      // has a kink at the sphere's centre that trilinear interpolation rounds off.
      const double within = expected > 0.0 ? 0.1 : 0.5 * h;
      EXPECT_NEAR(found.distance_mm, expected, within) << "voxel " << h << " mm";
      // The needle point is where the closed form has it: its distance from the centre.
      EXPECT_NEAR((found.needle_lps_mm - centre).norm() - radius - needle_radius, expected, within);
    }
  }
}

TEST(Clearance, AnArcPastACylinderMatchesTheClosedFormAtEveryVoxelSize) {
  // The arc: centre C, radius Ra in the plane z = 4, angles 0.3-1.9 rad. The cylinder: axis
  // along z through Q, radius Rc. The distance from an arc point to the axis is its distance to Q
  // in the plane: |Ra - |Q - C|| where Q's angle lies within the arc's, else the ends'.
  const Eigen::Vector2d c(0, 0);
  const double ra = 35.5, a0 = 0.3, a1 = 1.9, rc = 2.0, needle_radius = 0.6;
  std::vector<Eigen::Vector3d> arc;
  for (int i = 0; i <= 80; ++i) {
    const double a = a0 + (a1 - a0) * i / 80.0;
    arc.emplace_back(c.x() + ra * std::cos(a), c.y() + ra * std::sin(a), 4.0);
  }
  for (const Eigen::Vector2d& q :
       {Eigen::Vector2d(12.0, 25.0), Eigen::Vector2d(-8.0, 40.0), Eigen::Vector2d(36.0, -4.0),
        Eigen::Vector2d(21.0, 32.5), Eigen::Vector2d(20.0, 31.2)}) {
    const auto cylinder = [&](const Eigen::Vector3d& p) { return (p.head<2>() - q).norm() - rc; };
    const double angle = std::atan2(q.y() - c.y(), q.x() - c.x());
    double axis_mm = std::abs(ra - (q - c).norm());
    if (angle < a0 || angle > a1) {
      axis_mm = std::min((arc.front().head<2>() - q).norm(), (arc.back().head<2>() - q).norm());
    }
    const double expected = axis_mm - rc - needle_radius;
    for (const double h : {0.5, 1.0, 2.0}) {
      const auto field = DistanceField::fromFunction(
          gridAround({-50, -50, -10}, {50, 60, 20}, Eigen::Vector3d::Constant(h)), cylinder, 0.0);
      const auto found = closestApproach({{arc, needle_radius}}, field, 0.1);
      // The last arc enters the cylinder: its depth is known to the field's resolution.
      EXPECT_NEAR(found.distance_mm, expected, expected > 0.0 ? 0.1 : 0.5 * h)
          << "Q (" << q.transpose() << "), voxel " << h << " mm";
    }
  }
}

// A box whose faces lie on voxel faces is drawn exactly by its mask: the mask's field then gives
// the closed form too, with thick slices as well as thin ones.
TEST(Clearance, AMaskDrawnExactlyGivesTheClosedFormWithThickSlicesToo) {
  for (const Eigen::Vector3d& spacing :
       {Eigen::Vector3d(0.5, 0.5, 0.5), Eigen::Vector3d(0.7, 0.7, 2.5),
        Eigen::Vector3d(1.0, 1.0, 1.0)}) {
    Mask mask;
    mask.geometry.spacing_mm = spacing;
    mask.geometry.dims = {12, 10, 6};
    mask.geometry.origin_lps_mm = Eigen::Vector3d(1.0, 2.0, 3.0);
    mask.inside.assign(mask.geometry.voxelCount(), 1);
    // The box: voxel centres' hull plus half a voxel on every side.
    const Eigen::Vector3d lo = mask.geometry.origin_lps_mm - 0.5 * spacing;
    const Eigen::Vector3d hi =
        lo + Eigen::Vector3d(12 * spacing.x(), 10 * spacing.y(), 6 * spacing.z());
    const auto field = DistanceField::fromMask(mask, 10.0);
    const auto boxDistance = [&](const Eigen::Vector3d& p) {
      return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).norm();
    };
    const double r = 0.3;
    for (const auto& [a, b] : std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>{
             {{-10, hi.y() + 2.2, 4}, {20, hi.y() + 2.2, 5}},                       // along a face
             {{hi.x() + 1.3, hi.y() + 1.1, -5}, {hi.x() + 1.3, hi.y() + 1.1, 20}},  // an edge
             {{-5, 3, hi.z() + 4.0}, {15, 6, hi.z() + 3.0}}}) {                     // over the top
      double expected = 1e9;
      for (int i = 0; i <= 20000; ++i)
        expected = std::min(expected, boxDistance(a + (b - a) * (i / 20000.0)));
      const auto found = closestApproach({{segment(a, b, 3), r}}, field, 0.1);
      EXPECT_NEAR(found.distance_mm, expected - r, 0.1) << "spacing " << spacing.transpose();
    }
  }
}

// A sphere drawn by its voxels is known to half a voxel; the clearance from its mask says so.
TEST(Clearance, AVoxelisedSphereIsKnownToHalfAVoxel) {
  const Eigen::Vector3d centre(0.2, 0.1, -0.3);
  const double radius = 8.0;
  for (const double h : {0.5, 1.0}) {
    volume::Geometry grid =
        gridAround(centre.array() - 12.0, centre.array() + 12.0, Eigen::Vector3d::Constant(h));
    std::vector<std::uint8_t> inside(grid.voxelCount(), 0);
    std::size_t n = 0;
    for (int k = 0; k < grid.dims[2]; ++k)
      for (int j = 0; j < grid.dims[1]; ++j)
        for (int i = 0; i < grid.dims[0]; ++i, ++n)
          inside[n] = (grid.toLps(Eigen::Vector3d(i, j, k)) - centre).norm() <= radius;
    auto mask = cropMask(grid, inside, "sphere");
    ASSERT_TRUE(mask.ok());
    const auto field = DistanceField::fromMask(*mask, 15.0);
    for (const Eigen::Vector3d& dir : {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 1, 0),
                                       Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(-0.3, 0.8, 0.5)}) {
      const Eigen::Vector3d u = dir.normalized();
      const Eigen::Vector3d side = u.unitOrthogonal();
      const Eigen::Vector3d mid = centre + u * (radius + 3.0);
      const auto found =
          closestApproach({{segment(mid - 20 * side, mid + 20 * side, 4), 0.5}}, field, 0.1);
      EXPECT_NEAR(found.distance_mm, 2.5, 0.5 * h * std::sqrt(3.0)) << "voxel " << h;
    }
  }
}

TEST(Clearance, FarAwayTissueIsALowerBoundAndAnEmptyBodyIsInfinitelyFar) {
  Mask mask;
  mask.geometry.dims = {2, 2, 2};
  mask.inside.assign(8, 1);
  const auto field = DistanceField::fromMask(mask, 5.0);
  EXPECT_GE(field.reach_mm(), 5.0);
  const Eigen::Vector3d far(100, 0, 0);
  EXPECT_LE(field.at(far), (far - Eigen::Vector3d(1.5, 0, 0)).norm() + 1e-9);
  EXPECT_GE(field.at(far), 90.0);
  EXPECT_TRUE(std::isinf(closestApproach({}, field).distance_mm));
}

}  // namespace
}  // namespace ignav::anatomy
