// Isodose lines (issue 42, part 5) against closed forms: trilinear dose between voxel centres is
// exact for a linear field; an inverse-square dose's isodose at p % of the prescription is the
// circle r_p = r_100 · √(100 / p), found in the rendered slice's pixels of each level's colour.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include <opencv2/imgcodecs.hpp>

#include "ignav/dosimetry/isodose.hpp"

namespace ignav::dosimetry {
namespace {

volume::Geometry cube(double half_mm, double spacing_mm) {
  volume::Geometry g;
  const int n = static_cast<int>(std::lround(2.0 * half_mm / spacing_mm)) + 1;
  g.dims = {n, n, n};
  g.spacing_mm = Eigen::Vector3d::Constant(spacing_mm);
  g.origin_lps_mm = Eigen::Vector3d::Constant(-half_mm);
  return g;
}

std::vector<float> field(const volume::Geometry& g,
                         const std::function<double(const Eigen::Vector3d&)>& f) {
  std::vector<float> out(g.voxelCount());
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i)
        out[(static_cast<std::size_t>(k) * g.dims[1] + j) * g.dims[0] + i] =
            static_cast<float>(f(g.toLps(Eigen::Vector3d(i, j, k))));
  return out;
}

TEST(Isodose, DoseBetweenVoxelCentresIsExactForALinearField) {
  const auto g = cube(10.0, 2.0);
  const auto linear = [](const Eigen::Vector3d& p) {
    return 5.0 + 0.5 * p.x() - 0.25 * p.y() + 0.125 * p.z();
  };
  const auto dose = field(g, linear);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> inside(-10.0, 10.0);
  for (int n = 0; n < 200; ++n) {
    const Eigen::Vector3d p(inside(rng), inside(rng), inside(rng));
    EXPECT_NEAR(doseAt(dose, g, p), linear(p), 1e-5);
  }
  EXPECT_NEAR(doseAt(dose, g, Eigen::Vector3d(10, 10, 10)), linear({10, 10, 10}), 1e-5);
  EXPECT_TRUE(std::isnan(doseAt(dose, g, Eigen::Vector3d(10.5, 0, 0))));
}

TEST(Isodose, AnInverseSquareDosesIsodosesAreItsCircles) {
  // D(r) = k / r²; the prescription at 15 mm, so the p % line lies at 15 · √(100 / p) mm.
  const auto g = cube(30.0, 1.0);
  const double rx_Gy = 145.0, k = rx_Gy * 15.0 * 15.0;
  const auto dose = std::make_shared<const std::vector<float>>(
      field(g, [&](const Eigen::Vector3d& p) { return k / std::max(p.squaredNorm(), 0.25); }));
  auto overlays = isodoseOverlays(dose, g, rx_Gy);
  ASSERT_EQ(overlays.size(), 4u);
  EXPECT_EQ(overlays[1].label, "100 %");
  for (auto& o : overlays)
    o.label.clear();  // only the lines: their pixels are then exactly their colours
  // An axial slice through z = 0.3 mm, 0.25 mm pixels, centred on the source.
  volume::Slice s;
  s.width = s.height = 240;
  s.values.assign(240 * 240, 40.0f);
  s.pixel_size_mm = 0.25;
  s.window = volume::kWindowSoftTissue;
  s.pixel_to_lps.setIdentity();
  s.pixel_to_lps.block<3, 1>(0, 0) = Eigen::Vector3d(0.25, 0, 0);
  s.pixel_to_lps.block<3, 1>(0, 1) = Eigen::Vector3d(0, 0.25, 0);
  s.pixel_to_lps.block<3, 1>(0, 3) = Eigen::Vector3d(-29.875, -29.875, 0.3);
  volume::Overlays ov;
  ov.regions = overlays;
  volume::RenderOptions bare;  // no scale bar (white) or orientation letters
  bare.scale_bar = false;
  bare.orientation_labels = false;
  const auto png = volume::renderPng(s, ov, bare);
  ASSERT_TRUE(png.ok());
  const cv::Mat img = cv::imdecode(
      cv::Mat(1, static_cast<int>(png->size()), CV_8U, const_cast<std::uint8_t*>(png->data())),
      cv::IMREAD_COLOR);
  const auto levels = standardIsodoseLevels();
  for (const auto& level : levels) {
    const double r_expected = std::sqrt(15.0 * 15.0 * 100.0 / level.percent - 0.09);  // in-plane
    int n = 0;
    double lo = 1e9, hi = 0.0;
    for (int v = 0; v < img.rows; ++v)
      for (int u = 0; u < img.cols; ++u) {
        const cv::Vec3b bgr = img.at<cv::Vec3b>(v, u);
        if (bgr[2] != level.colour.r || bgr[1] != level.colour.g || bgr[0] != level.colour.b)
          continue;
        const double r = std::hypot(-29.875 + 0.25 * u, -29.875 + 0.25 * v);
        lo = std::min(lo, r);
        hi = std::max(hi, r);
        ++n;
      }
    // The outline: pixels inside with a neighbour outside, so within a pixel (0.25 mm) inside
    // the circle; the trilinear dose on 1 mm voxels moves it by hundredths of a millimetre.
    EXPECT_GT(n, static_cast<int>(2 * M_PI * r_expected / 0.25 * 0.8)) << level.percent;
    EXPECT_GT(lo, r_expected - 0.35) << level.percent;
    EXPECT_LT(hi, r_expected + 0.1) << level.percent;
    std::printf("%g %%: %d pixels from %.2f to %.2f mm, the circle %.2f mm\n", level.percent, n, lo,
                hi, r_expected);
  }
}

}  // namespace
}  // namespace ignav::dosimetry
