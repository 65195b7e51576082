// Reslicing checked against closed forms: a volume whose value is linear in LPS (trilinear
// interpolation reproduces it exactly), and hand-written pixel -> LPS maps per view.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "ignav/volume/slice.hpp"

namespace ignav::volume {
namespace {

// A rotated, anisotropic volume whose physical value is f(p) = a . (p - origin) + b for LPS p.
struct LinearVolume {
  Volume volume;
  Eigen::Vector3d gradient;  // df/dLPS
  double base = 0.0;
  double f(const Eigen::Vector3d& p) const {
    return gradient.dot(p - volume.geometry.origin_lps_mm) + base;
  }
};

LinearVolume linearVolume() {
  LinearVolume lv;
  Geometry& g = lv.volume.geometry;
  g.dims = {24, 20, 16};
  g.spacing_mm = {0.8, 1.1, 2.0};
  g.origin_lps_mm = {-12.5, 4.25, -30.0};
  // Rotation by 0.4 rad about (1, 2, 2)/3, built from its closed form (Rodrigues).
  const Eigen::Vector3d axis(1.0 / 3, 2.0 / 3, 2.0 / 3);
  Eigen::Matrix3d k;
  k << 0, -axis.z(), axis.y(), axis.z(), 0, -axis.x(), -axis.y(), axis.x(), 0;
  g.direction = Eigen::Matrix3d::Identity() + std::sin(0.4) * k + (1 - std::cos(0.4)) * k * k;
  // Stored value 3 i - 2 j + 5 k + 40 (an integer), physical = stored * 0.5 - 20.
  lv.volume.value_scale = 0.5;
  lv.volume.value_offset = -20.0;
  lv.volume.voxels.resize(g.voxelCount());
  for (int kk = 0; kk < g.dims[2]; ++kk)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        lv.volume.voxels[lv.volume.index(i, j, kk)] =
            static_cast<std::int16_t>(3 * i - 2 * j + 5 * kk + 40);
      }
  // i = (d_i . (p - o)) / s_i, so f = 0.5 * sum_a c_a d_a / s_a . (p - o) + 0.5 * 40 - 20.
  const Eigen::Vector3d c(3, -2, 5);
  lv.gradient = 0.5 * (g.direction.col(0) * c[0] / g.spacing_mm[0] +
                       g.direction.col(1) * c[1] / g.spacing_mm[1] +
                       g.direction.col(2) * c[2] / g.spacing_mm[2]);
  lv.base = 0.0;
  return lv;
}

void expectLinear(const LinearVolume& lv, const Slice& s) {
  int inside = 0;
  for (int v = 0; v < s.height; ++v) {
    for (int u = 0; u < s.width; ++u) {
      const float value = s.at(u, v);
      if (std::isnan(value)) continue;
      ++inside;
      ASSERT_NEAR(value, lv.f(s.pixelToLps(u, v)), 2e-4) << u << ", " << v;
    }
  }
  EXPECT_GT(inside, s.width * s.height / 10);
}

SliceSpec spec(View view, const Eigen::Vector3d& centre) {
  SliceSpec sp;
  sp.view = view;
  sp.centre_lps_mm = centre;
  sp.width_px = 41;
  sp.height_px = 31;
  sp.pixel_size_mm = 0.7;
  return sp;
}

TEST(Reslice, StandardViewsMapPixelsAsRadiologistsRead) {
  const LinearVolume lv = linearVolume();
  const Eigen::Vector3d c = volumeCentreLps(lv.volume.geometry);
  // Expected +u and +v directions in LPS, written out per view.
  const struct {
    View view;
    Eigen::Vector3d u, v;
  } views[] = {
      {View::kAxial, {1, 0, 0}, {0, 1, 0}},      // right = L, down = P
      {View::kCoronal, {1, 0, 0}, {0, 0, -1}},   // right = L, down = I
      {View::kSagittal, {0, 1, 0}, {0, 0, -1}},  // right = P, down = I
  };
  for (const auto& vw : views) {
    const auto s = reslice(lv.volume, spec(vw.view, c));
    ASSERT_TRUE(s.ok()) << s.error().message;
    ASSERT_EQ(s->width, 41);
    ASSERT_EQ(s->height, 31);
    for (int v : {0, 7, 30}) {
      for (int u : {0, 20, 40}) {
        const Eigen::Vector3d expected = c + (u - 20) * 0.7 * vw.u + (v - 15) * 0.7 * vw.v;
        EXPECT_LT((s->pixelToLps(u, v) - expected).norm(), 1e-9);
      }
    }
    expectLinear(lv, *s);
  }
}

TEST(Reslice, ObliqueSliceSamplesTheLinearFunction) {
  const LinearVolume lv = linearVolume();
  SliceSpec sp =
      spec(View::kOblique, volumeCentreLps(lv.volume.geometry) + Eigen::Vector3d(1, -2, 3));
  sp.oblique_u = Eigen::Vector3d(1, 1, 1).normalized();
  sp.oblique_v = Eigen::Vector3d(1, -1, 0).normalized();
  const auto s = reslice(lv.volume, sp);
  ASSERT_TRUE(s.ok()) << s.error().message;
  expectLinear(lv, *s);
  // The centre lands on the central pixel.
  EXPECT_LT((s->pixelToLps(20, 15) - sp.centre_lps_mm).norm(), 1e-9);
}

TEST(Reslice, PixelToLpsToPixelRoundTrip) {
  const LinearVolume lv = linearVolume();
  SliceSpec sp = spec(View::kOblique, {3, -4, 5});
  sp.oblique_u = Eigen::Vector3d(0.6, 0, 0.8);
  sp.oblique_v = Eigen::Vector3d(0, -1, 0);
  for (View view : {View::kAxial, View::kSagittal, View::kCoronal, View::kOblique}) {
    sp.view = view;
    const auto s = reslice(lv.volume, sp);
    ASSERT_TRUE(s.ok()) << s.error().message;
    for (double u = -3.25; u < 45; u += 6.1) {
      for (double v = -2.5; v < 35; v += 4.3) {
        const Eigen::Vector3d p = s->pixelToLps(u, v);
        const Eigen::Vector3d back = s->lpsToPixel(p);
        EXPECT_NEAR(back.x(), u, 1e-9);
        EXPECT_NEAR(back.y(), v, 1e-9);
        EXPECT_NEAR(back.z(), 0.0, 1e-9);
        // A point 2.5 mm along the normal (away from the viewer) reads d = +2.5.
        const Eigen::Vector3d normal = s->pixel_to_lps.block<3, 1>(0, 2);
        EXPECT_NEAR(s->lpsToPixel(p + 2.5 * normal).z(), 2.5, 1e-9);
        // pixel_to_lps is the documented 4x4: LPS = M (u, v, 0, 1).
        EXPECT_LT(((s->pixel_to_lps * Eigen::Vector4d(u, v, 0, 1)).head<3>() - p).norm(), 1e-9);
      }
    }
  }
}

TEST(Reslice, OrientationLabelsPerView) {
  const LinearVolume lv = linearVolume();
  const Eigen::Vector3d c = volumeCentreLps(lv.volume.geometry);
  const auto axial = orientationLabels(*reslice(lv.volume, spec(View::kAxial, c)));
  EXPECT_EQ(axial.left, "R");
  EXPECT_EQ(axial.right, "L");
  EXPECT_EQ(axial.top, "A");
  EXPECT_EQ(axial.bottom, "P");
  const auto coronal = orientationLabels(*reslice(lv.volume, spec(View::kCoronal, c)));
  EXPECT_EQ(coronal.left, "R");
  EXPECT_EQ(coronal.right, "L");
  EXPECT_EQ(coronal.top, "S");
  EXPECT_EQ(coronal.bottom, "I");
  const auto sagittal = orientationLabels(*reslice(lv.volume, spec(View::kSagittal, c)));
  EXPECT_EQ(sagittal.left, "A");
  EXPECT_EQ(sagittal.right, "P");
  EXPECT_EQ(sagittal.top, "S");
  EXPECT_EQ(sagittal.bottom, "I");
  SliceSpec sp = spec(View::kOblique, c);
  sp.oblique_u = Eigen::Vector3d(0.8, -0.6, 0);  // mostly left, some anterior
  sp.oblique_v = Eigen::Vector3d(0, 0, -1);
  const auto oblique = orientationLabels(*reslice(lv.volume, sp));
  EXPECT_EQ(oblique.right, "LA");
  EXPECT_EQ(oblique.left, "RP");
  EXPECT_EQ(oblique.top, "S");
}

TEST(Reslice, DefaultsFitTheVolumeAtItsFinestSpacing) {
  Volume vol;
  vol.geometry.dims = {10, 20, 5};
  vol.geometry.spacing_mm = {0.7, 0.9, 3.0};
  vol.voxels.assign(vol.geometry.voxelCount(), 100);
  SliceSpec sp;
  sp.centre_lps_mm = volumeCentreLps(vol.geometry);
  const auto axial = reslice(vol, sp);
  ASSERT_TRUE(axial.ok()) << axial.error().message;
  EXPECT_DOUBLE_EQ(axial->pixel_size_mm, 0.7);
  EXPECT_DOUBLE_EQ(axial->thickness_mm, 3.0);
  // Extent 6.3 mm x 17.1 mm at 0.7 mm: 9 + 1 and 24.4 + 1 pixels, rounded up to odd.
  EXPECT_EQ(axial->width, 11);
  EXPECT_EQ(axial->height, 27);
  EXPECT_FLOAT_EQ(axial->at(5, 13), 100.0f);
  sp.view = View::kSagittal;
  const auto sagittal = reslice(vol, sp);
  ASSERT_TRUE(sagittal.ok());
  EXPECT_DOUBLE_EQ(sagittal->pixel_size_mm, 0.9);
  EXPECT_DOUBLE_EQ(sagittal->thickness_mm, 0.7);
  EXPECT_TRUE(std::isnan(sagittal->at(0, 0)));  // beyond the volume
}

TEST(Reslice, RejectsBadSpecs) {
  const LinearVolume lv = linearVolume();
  const Eigen::Vector3d c = volumeCentreLps(lv.volume.geometry);
  auto expectInvalid = [&](const SliceSpec& sp, const char* says) {
    const auto s = reslice(lv.volume, sp);
    ASSERT_FALSE(s.ok()) << says;
    EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(s.error().message.find(says), std::string::npos) << s.error().message;
  };
  SliceSpec sp = spec(View::kAxial, c);
  sp.centre_lps_mm.y() = std::numeric_limits<double>::quiet_NaN();
  expectInvalid(sp, "not finite");
  sp = spec(View::kAxial, c);
  sp.width_px = 5000;
  expectInvalid(sp, "width 5000");
  sp.width_px = -3;
  expectInvalid(sp, "width -3");
  sp = spec(View::kAxial, c);
  sp.pixel_size_mm = -1;
  expectInvalid(sp, "pixel size");
  sp = spec(View::kOblique, c);
  expectInvalid(sp, "needs both");
  sp.oblique_u = Eigen::Vector3d(1, 0, 0);
  sp.oblique_v = Eigen::Vector3d(0, 2, 0);
  expectInvalid(sp, "unit");
  sp.oblique_v = Eigen::Vector3d(0.6, 0.8, 0);
  expectInvalid(sp, "orthogonal");
}

// The imaged box is every voxel with its half-voxel margin. Points placed along the rotated,
// anisotropic grid's own axes lie at closed-form distances from it.
TEST(Geometry, OutsideByIsTheDistanceToTheImagedBox) {
  const LinearVolume lv = linearVolume();
  const Geometry& g = lv.volume.geometry;
  const Eigen::Vector3d& sp = g.spacing_mm;
  const auto at = [&](double i, double j, double k) { return g.toLps({i, j, k}); };
  EXPECT_EQ(g.outsideBy_mm(at(3, 4, 5)), 0.0);
  EXPECT_EQ(g.outsideBy_mm(at(-0.49, 19.49, 15.49)), 0.0);  // inside the outermost voxels' margin
  EXPECT_NEAR(g.outsideBy_mm(at(-2.5, 4, 5)), 2.0 * sp[0], 1e-9);  // two voxels before i = -0.5
  EXPECT_NEAR(g.outsideBy_mm(at(3, 20.5, 5)), 1.0 * sp[1], 1e-9);  // one voxel past j = 19.5
  // Past an edge (i and k at once): Pythagoras.
  EXPECT_NEAR(g.outsideBy_mm(at(25.5, 4, -3.5)), std::hypot(2.0 * sp[0], 3.0 * sp[2]), 1e-9);
  // Past a corner: all three.
  EXPECT_NEAR(g.outsideBy_mm(at(-1.5, -1.5, 17.5)),
              std::sqrt(sp[0] * sp[0] + sp[1] * sp[1] + 4.0 * sp[2] * sp[2]), 1e-9);
}

}  // namespace
}  // namespace ignav::volume
