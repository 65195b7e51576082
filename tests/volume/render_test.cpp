// Rendered PNGs decoded with OpenCV and checked pixel by pixel: grey levels from the window
// formula, markers at their projected pixels, translucent regions, scale bar and labels.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>

#include "ignav/volume/render.hpp"

namespace ignav::volume {
namespace {

// 64 x 48 axial slice, 0.5 mm pixels, pixel (0, 0) at LPS (-16, -12, 7), 2 mm thick.
Slice flatSlice(float value) {
  Slice s;
  s.width = 64;
  s.height = 48;
  s.values.assign(64 * 48, value);
  s.pixel_size_mm = 0.5;
  s.thickness_mm = 2.0;
  s.window = kWindowSoftTissue;  // W400 L40: [-160, 240] -> [0, 255]
  s.pixel_to_lps.setIdentity();
  s.pixel_to_lps.block<3, 1>(0, 0) = Eigen::Vector3d(0.5, 0, 0);
  s.pixel_to_lps.block<3, 1>(0, 1) = Eigen::Vector3d(0, 0.5, 0);
  s.pixel_to_lps.block<3, 1>(0, 3) = Eigen::Vector3d(-16, -12, 7);
  return s;
}

void set(Slice& s, int u, int v, float value) {
  s.values[static_cast<std::size_t>(v) * s.width + u] = value;
}

cv::Mat decode(const Expected<std::vector<std::uint8_t>>& png) {
  EXPECT_TRUE(png.ok()) << png.error().message;
  if (!png.ok()) return {};
  return cv::imdecode(
      cv::Mat(1, static_cast<int>(png->size()), CV_8U, const_cast<std::uint8_t*>(png->data())),
      cv::IMREAD_COLOR);
}

RenderOptions plain() {
  RenderOptions o;
  o.scale_bar = false;
  o.orientation_labels = false;
  return o;
}

// Decoded pixel as (r, g, b).
cv::Vec3i rgbAt(const cv::Mat& img, int u, int v) {
  const cv::Vec3b p = img.at<cv::Vec3b>(v, u);
  return {p[2], p[1], p[0]};
}

TEST(Render, WindowLevelMapsKnownValuesToKnownGreys) {
  Slice s = flatSlice(40.0f);
  set(s, 5, 5, -160.0f);   // window bottom
  set(s, 6, 5, 240.0f);    // window top
  set(s, 8, 5, 140.0f);    // 255 * 300 / 400 = 191.25
  set(s, 9, 5, -1000.0f);  // below: clamped
  set(s, 10, 5, std::numeric_limits<float>::quiet_NaN());
  RenderOptions o = plain();
  o.outside = {10, 20, 30};
  const cv::Mat img = decode(renderPng(s, {}, o));
  ASSERT_EQ(img.cols, 64);
  ASSERT_EQ(img.rows, 48);
  EXPECT_EQ(rgbAt(img, 5, 5), cv::Vec3i(0, 0, 0));
  EXPECT_EQ(rgbAt(img, 6, 5), cv::Vec3i(255, 255, 255));
  EXPECT_EQ(rgbAt(img, 7, 5), cv::Vec3i(128, 128, 128));  // level: 127.5 rounds up
  EXPECT_EQ(rgbAt(img, 8, 5), cv::Vec3i(191, 191, 191));
  EXPECT_EQ(rgbAt(img, 9, 5), cv::Vec3i(0, 0, 0));
  EXPECT_EQ(rgbAt(img, 10, 5), cv::Vec3i(10, 20, 30));
  // Lung window override: W1500 L-600 maps 40 HU to 255 * (40 + 1350) / 1500 = 236.3.
  o.window = kWindowLung;
  const cv::Mat lung = decode(renderPng(s, {}, o));
  EXPECT_EQ(rgbAt(lung, 7, 5)[0], 236);
}

TEST(Render, MarkersAtProjectedPixelsFilledOnPlaneHollowOff) {
  const Slice s = flatSlice(40.0f);
  Overlays ov;
  PointMarker on;
  on.lps_mm = {-6, 3, 7};  // pixel (20, 30), on the plane
  on.colour = {255, 0, 0};
  on.label = "T1";
  PointMarker off;
  off.lps_mm = {4, -2, 12};  // pixel (40, 20), 5 mm behind the plane (tolerance 1 mm)
  off.colour = {0, 0, 255};
  ov.points = {on, off};
  const cv::Mat img = decode(renderPng(s, ov, plain()));
  EXPECT_EQ(rgbAt(img, 20, 30), cv::Vec3i(255, 0, 0));
  EXPECT_EQ(rgbAt(img, 22, 31), cv::Vec3i(255, 0, 0));      // inside the filled disc
  EXPECT_EQ(rgbAt(img, 40, 20), cv::Vec3i(128, 128, 128));  // hollow centre
  EXPECT_EQ(rgbAt(img, 44, 20), cv::Vec3i(0, 0, 255));      // ring, radius 4
  EXPECT_EQ(rgbAt(img, 36, 20), cv::Vec3i(0, 0, 255));
}

TEST(Render, RegionPredicateAndPolygonAreTintedTranslucently) {
  const Slice s = flatSlice(40.0f);
  Overlays ov;
  RegionOverlay left;
  left.contains = [](const Eigen::Vector3d& p) { return p.x() < -10.0; };  // u < 12
  left.colour = {0, 255, 0};
  left.opacity = 0.25;
  RegionOverlay box;  // LPS square covering pixels 40..50 x 30..40
  box.polygon_lps_mm = {{4, 3, 7}, {9, 3, 7}, {9, 8, 7}, {4, 8, 7}};
  box.colour = {255, 0, 0};
  box.opacity = 0.5;
  ov.regions = {left, box};
  const cv::Mat img = decode(renderPng(s, ov, plain()));
  // 0.75 * 128 + 0.25 * (0, 255, 0) = (96, 159.75, 96)
  const cv::Vec3i tinted = rgbAt(img, 5, 40);
  EXPECT_EQ(tinted[0], 96);
  EXPECT_EQ(tinted[1], 160);
  EXPECT_EQ(tinted[2], 96);
  EXPECT_EQ(rgbAt(img, 12, 40), cv::Vec3i(128, 128, 128));  // u = 12 is x = -10: outside
  const cv::Vec3i red = rgbAt(img, 45, 35);                 // 0.5 * 128 + 0.5 * (255, 0, 0)
  EXPECT_NEAR(red[0], 192, 1);
  EXPECT_EQ(red[1], 64);
  EXPECT_EQ(rgbAt(img, 30, 35), cv::Vec3i(128, 128, 128));
}

TEST(Render, RegionBoundsLimitWhereThePredicateIsAsked) {
  // The slice is the plane z = 7 mm, pixels 0.5 mm: u = 2 (x + 16), v = 2 (y + 12).
  const Slice s = flatSlice(40.0f);
  int asked = 0;
  RegionOverlay ball;  // a 3 mm ball at (0, 0, 7): pixels (32, 24) +- 6
  ball.contains = [&](const Eigen::Vector3d& p) {
    ++asked;
    return (p - Eigen::Vector3d(0, 0, 7)).norm() <= 3.0;
  };
  for (int c = 0; c < 8; ++c) {  // its bounding cube
    ball.bounds_lps_mm.emplace_back(c & 1 ? 3 : -3, c & 2 ? 3 : -3, 7 + (c & 4 ? 3 : -3));
  }
  Overlays ov;
  ov.regions = {ball};
  const cv::Mat img = decode(renderPng(s, ov, plain()));
  EXPECT_NE(rgbAt(img, 32, 24), cv::Vec3i(128, 128, 128));  // tinted inside
  EXPECT_NE(rgbAt(img, 32, 30), cv::Vec3i(128, 128, 128));  // 3 mm off the centre: the edge
  EXPECT_EQ(rgbAt(img, 32, 31), cv::Vec3i(128, 128, 128));
  EXPECT_GT(asked, 12 * 12);  // every pixel of the ball's box was asked
  EXPECT_LE(asked, 15 * 15);  // and little else of the 64 x 48
  // The same ball 5 mm off the plane: the slice misses its box, nothing is asked or tinted.
  asked = 0;
  for (auto& corner : ov.regions[0].bounds_lps_mm)
    corner.z() += 6.5;
  ov.regions[0].contains = [&](const Eigen::Vector3d&) {
    ++asked;
    return true;
  };
  const cv::Mat beside = decode(renderPng(s, ov, plain()));
  EXPECT_EQ(asked, 0);
  EXPECT_EQ(rgbAt(beside, 32, 24), cv::Vec3i(128, 128, 128));
}

// A segmentation's structure over the CT: its outline in its colour, the inside left grey.
TEST(Render, ARegionDrawnAsAnOutlineColoursOnlyItsEdge) {
  const Slice s = flatSlice(40.0f);  // z = 7 mm, pixels 0.5 mm: u = 2 (x + 16), v = 2 (y + 12)
  RegionOverlay ball;                // a 3 mm disc at (0, 0): pixels (32, 24) +- 6
  ball.contains = [](const Eigen::Vector3d& p) {
    return (p - Eigen::Vector3d(0, 0, 7)).norm() <= 3.0;
  };
  for (int c = 0; c < 8; ++c)
    ball.bounds_lps_mm.emplace_back(c & 1 ? 3 : -3, c & 2 ? 3 : -3, 7 + (c & 4 ? 3 : -3));
  ball.colour = {255, 230, 51};
  ball.opacity = 1.0;
  ball.outline = true;
  Overlays ov;
  ov.regions = {ball};
  const cv::Mat img = decode(renderPng(s, ov, plain()));
  EXPECT_EQ(rgbAt(img, 32, 24), cv::Vec3i(128, 128, 128));  // the inside stays grey
  EXPECT_EQ(rgbAt(img, 32, 30), cv::Vec3i(255, 230, 51));   // 3 mm off the centre: the edge
  EXPECT_EQ(rgbAt(img, 26, 24), cv::Vec3i(255, 230, 51));
  EXPECT_EQ(rgbAt(img, 32, 31), cv::Vec3i(128, 128, 128));  // outside
  int edge = 0;
  for (int v = 0; v < img.rows; ++v)
    for (int u = 0; u < img.cols; ++u)
      edge += rgbAt(img, u, v) == cv::Vec3i(255, 230, 51);
  EXPECT_GT(edge, 20);  // a ring about 2π·6 pixels long
  EXPECT_LT(edge, 60);
}

// Its name beside it: up and to the right of the outline's topmost pixel, in its colour; nothing
// else on the slice changes.
TEST(Render, AnOutlinesLabelIsDrawnByItsTopmostPixel) {
  const Slice s = flatSlice(40.0f);
  RegionOverlay ball;  // a 3 mm disc at (0, 0): pixels (32, 24) +- 6, its top row v = 18
  ball.contains = [](const Eigen::Vector3d& p) {
    return (p - Eigen::Vector3d(0, 0, 7)).norm() <= 3.0;
  };
  ball.colour = {255, 230, 51};
  ball.opacity = 1.0;
  ball.outline = true;
  Overlays plain_ov, labelled_ov;
  plain_ov.regions = {ball};
  ball.label = "urethra";
  labelled_ov.regions = {ball};
  const cv::Mat plain_img = decode(renderPng(s, plain_ov, plain()));
  const cv::Mat labelled = decode(renderPng(s, labelled_ov, plain()));
  int changed = 0, inked = 0;
  for (int v = 0; v < labelled.rows; ++v)
    for (int u = 0; u < labelled.cols; ++u) {
      if (rgbAt(labelled, u, v) == rgbAt(plain_img, u, v)) continue;
      ++changed;
      // Within the text's box: from the top pixel's column, ending a few rows below its row.
      EXPECT_GE(u, 32 + 3 - 5) << u << ", " << v;
      EXPECT_LE(v, 18) << u << ", " << v;
      EXPECT_GE(v, 18 - 20) << u << ", " << v;
      const cv::Vec3i c = rgbAt(labelled, u, v);
      inked += c[0] > 160 && c[1] > 140 && c[2] < 110;  // the outline's yellow, antialiased
    }
  EXPECT_GT(changed, 50);
  EXPECT_GT(inked, 5);

  // A structure cut by the image's top edge: its name below the edge, not above it (unseen).
  RegionOverlay cut = ball;
  cut.contains = [](const Eigen::Vector3d& p) {
    return (p - Eigen::Vector3d(0, -12, 7)).norm() <= 3.0;  // centred on the top row
  };
  Overlays cut_plain, cut_labelled;
  cut.label = "";
  cut_plain.regions = {cut};
  cut.label = "rectum";
  cut_labelled.regions = {cut};
  const cv::Mat a = decode(renderPng(s, cut_plain, plain()));
  const cv::Mat b = decode(renderPng(s, cut_labelled, plain()));
  int shown = 0;
  for (int v = 0; v < a.rows; ++v)
    for (int u = 0; u < a.cols; ++u)
      shown += rgbAt(a, u, v) != rgbAt(b, u, v);
  EXPECT_GT(shown, 50);
}

TEST(Render, PathIsDrawnThroughProjectedPoints) {
  const Slice s = flatSlice(40.0f);
  Overlays ov;
  PathOverlay path;
  path.lps_mm = {{-11, -7, 7}, {9, -7, 9}};  // pixels (10, 10) -> (50, 10), 2 mm off at the end
  path.colour = {0, 255, 255};
  ov.paths = {path};
  const cv::Mat img = decode(renderPng(s, ov, plain()));
  const cv::Vec3i mid = rgbAt(img, 30, 10);
  EXPECT_LT(mid[0], 40);
  EXPECT_GT(mid[1], 220);
  EXPECT_GT(mid[2], 220);
  EXPECT_EQ(rgbAt(img, 30, 20), cv::Vec3i(128, 128, 128));
}

// Labels are drawn once and blended from kept coverage masks (render.cpp, LabelCache): the
// picture must be OpenCV's own putText halo and text drawn on the same image, within 4 grey
// levels (OpenCV rounds after each of the overlapping strokes, the cache once per pixel),
// on a background that varies, for a label inside the slice and one cut by its right edge, and
// again when the labels come from the cache on a second slice.
TEST(Render, LabelsAreOpenCvsPutTextWithinRounding) {
  Slice s = flatSlice(0.0f);
  for (int v = 0; v < s.height; ++v)
    for (int u = 0; u < s.width; ++u)
      set(s, u, v, static_cast<float>(-160 + 9 * u + 3 * v % 170));
  Overlays labelled;
  PointMarker inside;
  inside.lps_mm = {-12, -6, 7};  // pixel (8, 12), on the plane
  inside.colour = {255, 64, 0};
  inside.label = "T12";
  PointMarker cut = inside;
  cut.lps_mm = {12.5, 8, 7};  // pixel (57, 40): its label runs past the right edge
  cut.colour = {0, 255, 255};
  cut.label = "F3";
  labelled.points = {inside, cut};
  Overlays unlabelled = labelled;
  for (auto& p : unlabelled.points)
    p.label.clear();

  // OpenCV clips its strokes at the image's edge, which lightens the halo in the last column; the
  // reference is drawn on the image with a margin around it, then cut back to the image.
  constexpr int kMargin = 8;
  const cv::Mat bare = decode(renderPng(s, unlabelled, plain()));
  cv::Mat framed;
  cv::copyMakeBorder(bare, framed, kMargin, kMargin, kMargin, kMargin, cv::BORDER_REPLICATE);
  for (const auto& [p, at] : {std::pair{inside, cv::Point(8, 12)}, {cut, cv::Point(57, 40)}}) {
    const cv::Point anchor(at.x + p.radius_px + 3 + kMargin, at.y + 4 + kMargin);
    const cv::Scalar colour(p.colour.b, p.colour.g, p.colour.r);
    cv::putText(framed, p.label, anchor, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 3,
                cv::LINE_AA);
    cv::putText(framed, p.label, anchor, cv::FONT_HERSHEY_SIMPLEX, 0.4, colour, 1, cv::LINE_AA);
  }
  const cv::Mat expected = framed(cv::Rect(kMargin, kMargin, s.width, s.height));
  SliceRenderer renderer;
  for (int round = 0; round < 2; ++round) {  // the second from the cache
    const cv::Mat got = decode(renderer.renderPng(s, labelled, plain()));
    ASSERT_EQ(got.size(), expected.size());
    cv::Mat diff;
    cv::absdiff(got, expected, diff);
    double worst = 0;
    cv::minMaxLoc(diff.reshape(1), nullptr, &worst);
    EXPECT_LE(worst, 4.0) << "round " << round;
    cv::Mat changed;
    cv::absdiff(got, bare, changed);
    EXPECT_GT(cv::countNonZero(changed.reshape(1)), 100) << "round " << round;  // labels drawn
  }
}

TEST(Render, ScaleBarAndOrientationLabels) {
  const Slice s = flatSlice(40.0f);
  const cv::Mat img = decode(renderPng(s, {}, RenderOptions{}));
  // Quarter width = 16 px = 8 mm, so the bar is 5 mm = 10 px along row h - 8 from x = 8.
  EXPECT_EQ(rgbAt(img, 12, 40), cv::Vec3i(255, 255, 255));
  EXPECT_EQ(rgbAt(img, 18, 40), cv::Vec3i(255, 255, 255));
  EXPECT_NE(rgbAt(img, 25, 40), cv::Vec3i(255, 255, 255));
  // The "L" label (light yellow) sits at the right edge, mid height.
  int yellow = 0;
  for (int v = 16; v < 32; ++v)
    for (int u = 52; u < 64; ++u) {
      const cv::Vec3i p = rgbAt(img, u, v);
      if (p[0] > 200 && p[1] > 200 && p[2] < 180) ++yellow;
    }
  EXPECT_GT(yellow, 3);
}

TEST(Render, ResliceThenRenderKeepsTheSliceSizeAndMapping) {
  // A 60 mm cube of water with a 10 mm bone sphere centred at LPS (5, -5, 0).
  Volume vol;
  vol.geometry.dims = {60, 60, 30};
  vol.geometry.spacing_mm = {1.0, 1.0, 2.0};
  vol.geometry.origin_lps_mm = {-29.5, -29.5, -29.0};
  vol.voxels.assign(vol.geometry.voxelCount(), 0);
  for (int k = 0; k < 30; ++k)
    for (int j = 0; j < 60; ++j)
      for (int i = 0; i < 60; ++i) {
        const Eigen::Vector3d p = vol.geometry.toLps(
            {static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)});
        if ((p - Eigen::Vector3d(5, -5, 0)).norm() < 10.0) vol.voxels[vol.index(i, j, k)] = 1000;
      }
  for (View view : {View::kAxial, View::kSagittal, View::kCoronal}) {
    SliceSpec spec;
    spec.view = view;
    spec.centre_lps_mm = {5, -5, 0};
    spec.window = kWindowBone;
    const auto slice = reslice(vol, spec);
    ASSERT_TRUE(slice.ok()) << slice.error().message;
    Overlays ov;
    ov.points.push_back({Eigen::Vector3d(5, -5, 0), "target", {255, 0, 0}, 3});
    const auto png = renderPng(*slice, ov);
    const cv::Mat img = decode(png);
    ASSERT_EQ(img.cols, slice->width);
    ASSERT_EQ(img.rows, slice->height);
    const Eigen::Vector3d uv = slice->lpsToPixel({5, -5, 0});
    EXPECT_EQ(
        rgbAt(img, static_cast<int>(std::lround(uv.x())), static_cast<int>(std::lround(uv.y()))),
        cv::Vec3i(255, 0, 0));
    // Bone (1000 HU) 7 mm from the target along -u (the label is on the right): (1000 - 400 + 900)
    // * 255 / 1800 = 212.5.
    const Eigen::Vector3d bone = slice->lpsToPixel(
        Eigen::Vector3d(5, -5, 0) - 7.0 * slice->pixel_to_lps.block<3, 1>(0, 0).normalized());
    EXPECT_EQ(rgbAt(img, static_cast<int>(std::lround(bone.x())),
                    static_cast<int>(std::lround(bone.y())))[0],
              213);
    if (const char* dir = std::getenv("IGNAV_RENDER_SAMPLES")) {
      ASSERT_TRUE(writePng(*png, std::string(dir) + "/view" +
                                     std::to_string(static_cast<int>(view)) + ".png")
                      .ok());
    }
  }
}

TEST(Render, RejectsInconsistentSliceAndBadWindowAndWritesFiles) {
  Slice s = flatSlice(0.0f);
  RenderOptions o;
  o.window = WindowLevel{0.0, 40.0};
  auto png = renderPng(s, {}, o);
  ASSERT_FALSE(png.ok());
  EXPECT_EQ(png.error().code, ErrorCode::kInvalidArgument);
  s.values.pop_back();
  png = renderPng(s);
  ASSERT_FALSE(png.ok());
  EXPECT_NE(png.error().message.find("64 x 48"), std::string::npos);
  s.values.push_back(0.0f);
  png = renderPng(s);
  ASSERT_TRUE(png.ok());
  const auto path = std::filesystem::temp_directory_path() / "ignav_render_test.png";
  ASSERT_TRUE(writePng(*png, path.string()).ok());
  EXPECT_EQ(cv::imread(path.string()).cols, 64);
  std::filesystem::remove(path);
  EXPECT_FALSE(writePng(*png, "/nonexistent-dir/x.png").ok());
}

}  // namespace
}  // namespace ignav::volume
