// Slice rendering with OpenCV: window/level to grey, then overlays in display order.
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <png.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>

#include "ignav/volume/render.hpp"

namespace ignav::volume {
namespace {

cv::Scalar bgr(const Rgb& c) {
  return cv::Scalar(c.b, c.g, c.r);
}

cv::Point toPoint(const Eigen::Vector3d& uvd) {
  return {static_cast<int>(std::lround(uvd.x())), static_cast<int>(std::lround(uvd.y()))};
}

bool projectable(const Eigen::Vector3d& uvd) {
  // Keep far-off points out of OpenCV's integer coordinates.
  return uvd.allFinite() && std::abs(uvd.x()) < 1e6 && std::abs(uvd.y()) < 1e6;
}

void blend(cv::Mat& img, int u, int v, const Rgb& c, double alpha) {
  auto& px = img.at<cv::Vec3b>(v, u);
  const double target[3] = {static_cast<double>(c.b), static_cast<double>(c.g),
                            static_cast<double>(c.r)};
  for (int k = 0; k < 3; ++k) {
    px[k] = cv::saturate_cast<uchar>((1.0 - alpha) * px[k] + alpha * target[k]);
  }
}

void drawRegion(cv::Mat& img, const Slice& slice, const RegionOverlay& region) {
  const double alpha = std::clamp(region.opacity, 0.0, 1.0);
  cv::Mat mask = cv::Mat::zeros(img.size(), CV_8U);
  if (region.polygon_lps_mm.size() >= 3) {
    std::vector<cv::Point> poly;
    for (const auto& p : region.polygon_lps_mm) {
      const Eigen::Vector3d uvd = slice.lpsToPixel(p);
      if (projectable(uvd)) poly.push_back(toPoint(uvd));
    }
    if (poly.size() >= 3) cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{poly}, 255);
  }
  for (int v = 0; v < img.rows; ++v) {
    for (int u = 0; u < img.cols; ++u) {
      bool inside = mask.at<uchar>(v, u) != 0;
      if (!inside && region.contains) inside = region.contains(slice.pixelToLps(u, v));
      if (inside) blend(img, u, v, region.colour, alpha);
    }
  }
}

void drawText(cv::Mat& img, const std::string& text, cv::Point anchor, const cv::Scalar& colour) {
  cv::putText(img, text, anchor, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 3,
              cv::LINE_AA);  // dark halo keeps labels readable on bone
  cv::putText(img, text, anchor, cv::FONT_HERSHEY_SIMPLEX, 0.4, colour, 1, cv::LINE_AA);
}

cv::Size textSize(const std::string& text) {
  int baseline = 0;
  return cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, 0.4, 1, &baseline);
}

void drawScaleBar(cv::Mat& img, double pixel_mm) {
  // The longest round length that fits in a quarter of the width.
  static const double kLengths_mm[] = {500, 200, 100, 50, 20, 10, 5, 2, 1};
  for (double len_mm : kLengths_mm) {
    const int len_px = static_cast<int>(std::lround(len_mm / pixel_mm));
    if (len_px > img.cols / 4 || len_px < 4) continue;
    const int x0 = 8, y = img.rows - 8;
    const cv::Scalar white(255, 255, 255);
    cv::line(img, {x0, y}, {x0 + len_px, y}, white, 1, cv::LINE_8);
    cv::line(img, {x0, y - 3}, {x0, y}, white, 1, cv::LINE_8);
    cv::line(img, {x0 + len_px, y - 3}, {x0 + len_px, y}, white, 1, cv::LINE_8);
    std::ostringstream label;
    label << len_mm << " mm";
    drawText(img, label.str(), {x0, y - 6}, white);
    return;
  }
}

void drawOrientation(cv::Mat& img, const Slice& slice) {
  const EdgeLabels labels = orientationLabels(slice);
  const cv::Scalar colour(128, 255, 255);  // light yellow
  const int w = img.cols, h = img.rows;
  const cv::Size l = textSize(labels.left), r = textSize(labels.right), t = textSize(labels.top),
                 b = textSize(labels.bottom);
  drawText(img, labels.left, {3, h / 2 + l.height / 2}, colour);
  drawText(img, labels.right, {w - r.width - 3, h / 2 + r.height / 2}, colour);
  drawText(img, labels.top, {w / 2 - t.width / 2, t.height + 3}, colour);
  drawText(img, labels.bottom, {w / 2 - b.width / 2, h - 4}, colour);
}

}  // namespace

std::uint8_t windowGrey(double value, const WindowLevel& window) {
  const double lo = window.level - 0.5 * window.width;
  const double g = 255.0 * (value - lo) / window.width;
  return static_cast<std::uint8_t>(std::lround(std::clamp(g, 0.0, 255.0)));
}

Expected<std::vector<std::uint8_t>> renderPng(const Slice& slice, const Overlays& overlays,
                                              const RenderOptions& options) {
  if (slice.width <= 0 || slice.height <= 0 ||
      slice.values.size() != static_cast<std::size_t>(slice.width) * slice.height) {
    return makeError(ErrorCode::kInvalidArgument,
                     "renderPng: slice is " + std::to_string(slice.width) + " x " +
                         std::to_string(slice.height) + " px but holds " +
                         std::to_string(slice.values.size()) + " values");
  }
  const WindowLevel window = options.window.value_or(slice.window);
  if (!std::isfinite(window.width) || window.width <= 0.0 || !std::isfinite(window.level)) {
    return makeError(ErrorCode::kInvalidArgument,
                     "renderPng: window width " + std::to_string(window.width) + " / level " +
                         std::to_string(window.level) + " must be finite, width positive");
  }
  const double tolerance_mm = options.in_plane_tolerance_mm > 0.0 ? options.in_plane_tolerance_mm
                                                                  : 0.5 * slice.thickness_mm;
  try {
    cv::Mat img(slice.height, slice.width, CV_8UC3);
    for (int v = 0; v < slice.height; ++v) {
      for (int u = 0; u < slice.width; ++u) {
        const float value = slice.at(u, v);
        if (std::isnan(value)) {
          img.at<cv::Vec3b>(v, u) =
              cv::Vec3b(options.outside.b, options.outside.g, options.outside.r);
        } else {
          const std::uint8_t g = windowGrey(value, window);
          img.at<cv::Vec3b>(v, u) = cv::Vec3b(g, g, g);
        }
      }
    }
    for (const auto& region : overlays.regions)
      drawRegion(img, slice, region);
    for (const auto& path : overlays.paths) {
      std::vector<cv::Point> pts;
      for (const auto& p : path.lps_mm) {
        const Eigen::Vector3d uvd = slice.lpsToPixel(p);
        if (projectable(uvd)) pts.push_back(toPoint(uvd));
      }
      if (pts.size() >= 2) {
        cv::polylines(img, pts, false, bgr(path.colour), std::max(1, path.thickness_px),
                      cv::LINE_AA);
      }
    }
    for (const auto& point : overlays.points) {
      const Eigen::Vector3d uvd = slice.lpsToPixel(point.lps_mm);
      if (!projectable(uvd)) continue;
      const cv::Point c = toPoint(uvd);
      const int r = std::max(1, point.radius_px);
      const bool in_plane = std::abs(uvd.z()) <= tolerance_mm;
      // Filled on the plane; a hollow ring when the point lies in front of or behind it.
      cv::circle(img, c, r, bgr(point.colour), in_plane ? cv::FILLED : 1, cv::LINE_8);
      if (!point.label.empty()) {
        drawText(img, point.label, {c.x + r + 3, c.y + 4}, bgr(point.colour));
      }
    }
    if (options.scale_bar) drawScaleBar(img, slice.pixel_size_mm);
    if (options.orientation_labels) drawOrientation(img, slice);

    return encodePngBgr(img.data, img.cols, img.rows, img.step[0]);
  } catch (const std::exception& e) {  // cv::Exception and bad_alloc must not cross the module
    return makeError(ErrorCode::kInternal, std::string("renderPng: ") + e.what());
  }
}

namespace {

// Where libpng writes: a buffer sized for the worst case beforehand, so nothing is allocated
// while libpng runs (its errors longjmp).
struct PngBuffer {
  std::uint8_t* data = nullptr;
  std::size_t capacity = 0;
  std::size_t size = 0;
};

void appendPng(png_structp png, png_bytep bytes, png_size_t count) {
  auto* out = static_cast<PngBuffer*>(png_get_io_ptr(png));
  if (count > out->capacity - out->size) png_error(png, "larger than its worst case");
  std::memcpy(out->data + out->size, bytes, count);
  out->size += count;
}

void flushPng(png_structp) {}

// libpng reports errors by longjmp: only trivially destructible locals live in this frame.
bool encodeRows(const std::uint8_t* bgr, png_uint_32 width, png_uint_32 height,
                std::size_t stride_bytes, PngBuffer* out) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, out, appendPng, flushPng);
  png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  // Slices go to a viewer at every scroll step: zlib's fastest level without row filters encodes
  // a 512² CT slice in 2.5-4.5 ms instead of 14-34 ms (libpng's defaults) for 1.1-1.6 times the
  // bytes (docs/PERFORMANCE.md, tools/bench/bench_render).
  png_set_compression_level(png, 1);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_NONE);
  png_write_info(png, info);
  png_set_bgr(png);
  for (png_uint_32 y = 0; y < height; ++y)
    png_write_row(png, bgr + y * stride_bytes);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

// libpng rather than OpenCV's imgcodecs, which on Debian links GDAL and ~120 libraries: that
// cost 0.14 s at every start of every program that renders. One pass (asking libpng's simplified
// API for the size first encoded every image twice, issue 28).
Expected<std::vector<std::uint8_t>> encodePngBgr(const std::uint8_t* bgr, int width, int height,
                                                 std::size_t stride_bytes) {
  if (width <= 0 || height <= 0 || stride_bytes < 3 * static_cast<std::size_t>(width)) {
    return makeError(ErrorCode::kInvalidArgument, "PNG: bad image size or stride");
  }
  // The worst case: the filtered rows deflated (zlib's bound), in IDAT chunks of at most 8 KiB
  // (12 bytes each around them), plus the signature, IHDR and IEND.
  const auto raw = static_cast<uLong>(height) * (3 * static_cast<uLong>(width) + 1);
  const std::size_t deflated = compressBound(raw);
  PngBuffer out;
  out.capacity = deflated + 12 * (deflated / 8192 + 1) + 1024;
  const std::unique_ptr<std::uint8_t[]> buffer(new std::uint8_t[out.capacity]);
  out.data = buffer.get();
  if (!encodeRows(bgr, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height),
                  stride_bytes, &out)) {
    return makeError(ErrorCode::kInternal, "PNG encoding failed (libpng)");
  }
  return std::vector<std::uint8_t>(out.data, out.data + out.size);
}

Status writePng(const std::vector<std::uint8_t>& png, const std::string& path) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return makeError(ErrorCode::kIo, path + ": cannot create the file");
  out.write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
  out.close();
  if (!out) return makeError(ErrorCode::kIo, path + ": writing failed (disk full?)");
  return Ok{};
}

}  // namespace ignav::volume
