// Slice rendering with OpenCV: window/level to grey, then overlays in display order.
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <libdeflate.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <unordered_map>

#include "ignav/volume/render.hpp"
#include "ignav/volume/volume.hpp"

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

// The pixels contains() must be asked about: the whole image, or the box of the region's bounds
// projected onto it (a pixel's margin around); none when the slice's plane misses the bounds.
cv::Rect askedPixels(const cv::Mat& img, const Slice& slice, const RegionOverlay& region) {
  const cv::Rect whole(0, 0, img.cols, img.rows);
  if (region.bounds_lps_mm.empty()) return whole;
  double u0 = INFINITY, u1 = -INFINITY, v0 = INFINITY, v1 = -INFINITY, d0 = INFINITY,
         d1 = -INFINITY;
  for (const auto& p : region.bounds_lps_mm) {
    const Eigen::Vector3d uvd = slice.lpsToPixel(p);
    u0 = std::min(u0, uvd.x());
    u1 = std::max(u1, uvd.x());
    v0 = std::min(v0, uvd.y());
    v1 = std::max(v1, uvd.y());
    d0 = std::min(d0, uvd.z());
    d1 = std::max(d1, uvd.z());
  }
  if (!(d0 <= 0.0 && d1 >= 0.0)) return {};  // the plane passes beside the hull (or NaN)
  const cv::Rect box(cv::Point(static_cast<int>(std::floor(std::max(u0, -1.0))),
                               static_cast<int>(std::floor(std::max(v0, -1.0)))),
                     cv::Point(static_cast<int>(std::ceil(std::min(u1, double(img.cols)))) + 1,
                               static_cast<int>(std::ceil(std::min(v1, double(img.rows)))) + 1));
  return box & whole;
}

// Returns, for an outline, its topmost pixel (the leftmost of those), where its label goes.
std::optional<cv::Point> drawRegion(cv::Mat& img, const Slice& slice, const RegionOverlay& region) {
  const double alpha = std::clamp(region.opacity, 0.0, 1.0);
  cv::Mat mask;
  if (region.polygon_lps_mm.size() >= 3) {
    std::vector<cv::Point> poly;
    for (const auto& p : region.polygon_lps_mm) {
      const Eigen::Vector3d uvd = slice.lpsToPixel(p);
      if (projectable(uvd)) poly.push_back(toPoint(uvd));
    }
    if (poly.size() >= 3) {
      mask = cv::Mat::zeros(img.size(), CV_8U);
      cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{poly}, 255);
      for (int v = 0; v < img.rows; ++v) {
        for (int u = 0; u < img.cols; ++u) {
          if (mask.at<uchar>(v, u) != 0) blend(img, u, v, region.colour, alpha);
        }
      }
    }
  }
  if (!region.contains) return std::nullopt;
  const cv::Rect asked = askedPixels(img, slice, region);
  if (region.outline) {
    if (asked.empty()) return std::nullopt;
    std::optional<cv::Point> top;
    cv::Mat inside = cv::Mat::zeros(asked.height + 2, asked.width + 2, CV_8U);  // a ring outside
    for (int v = 0; v < asked.height; ++v)
      for (int u = 0; u < asked.width; ++u)
        inside.at<uchar>(v + 1, u + 1) =
            region.contains(slice.pixelToLps(u + asked.x, v + asked.y)) ? 1 : 0;
    for (int v = 1; v <= asked.height; ++v)
      for (int u = 1; u <= asked.width; ++u) {
        if (inside.at<uchar>(v, u) && !(inside.at<uchar>(v - 1, u) && inside.at<uchar>(v + 1, u) &&
                                        inside.at<uchar>(v, u - 1) && inside.at<uchar>(v, u + 1))) {
          blend(img, u - 1 + asked.x, v - 1 + asked.y, region.colour, alpha);
          if (!top) top = cv::Point(u - 1 + asked.x, v - 1 + asked.y);  // rows top down
        }
      }
    return top;
  }
  for (int v = asked.y; v < asked.y + asked.height; ++v) {
    for (int u = asked.x; u < asked.x + asked.width; ++u) {
      if (!mask.empty() && mask.at<uchar>(v, u) != 0) continue;  // tinted once
      if (region.contains(slice.pixelToLps(u, v))) blend(img, u, v, region.colour, alpha);
    }
  }
  return std::nullopt;
}

cv::Size textSize(const std::string& text) {
  int baseline = 0;
  return cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, 0.4, 1, &baseline);
}

// Labels, each drawn once and kept as coverage masks. cv::putText allocates for every stroke of
// every glyph: under load with 100 labelled targets, half of the server's allocations were
// labels (heaptrack), and the same labels come back on every slice. A label is a dark halo (keeps
// it readable on bone) with the text over it, both antialiased. OpenCV blends each stroke as
// dst + (colour - dst) * a; drawn on black in 255, the strokes leave the coverage
// 1 - prod(1 - a), and blending that coverage into the image once gives the same picture up to
// rounding (within 4 grey levels of putText, tested in render_test).
class LabelCache {
 public:
  void draw(cv::Mat& img, const std::string& text, cv::Point anchor, const cv::Scalar& colour) {
    const Sprite& sprite = spriteOf(text);
    const int u0 = anchor.x - kPad_px, v0 = anchor.y - sprite.above_px;
    const cv::Rect onto =
        cv::Rect(u0, v0, sprite.halo.cols, sprite.halo.rows) & cv::Rect(0, 0, img.cols, img.rows);
    for (int v = onto.y; v < onto.y + onto.height; ++v) {
      const std::uint8_t* halo = sprite.halo.ptr<std::uint8_t>(v - v0);
      const std::uint8_t* ink = sprite.ink.ptr<std::uint8_t>(v - v0);
      std::uint8_t* row = img.ptr<std::uint8_t>(v);
      for (int u = onto.x; u < onto.x + onto.width; ++u) {
        const int a = halo[u - u0], b = ink[u - u0];
        if (a == 0 && b == 0) continue;
        for (int c = 0; c < 3; ++c) {
          const int dark = row[3 * u + c] * (255 - a);                               // x 255
          const int lit = dark * (255 - b) + static_cast<int>(colour[c]) * b * 255;  // x 255²
          row[3 * u + c] = static_cast<std::uint8_t>((lit + 255 * 255 / 2) / (255 * 255));
        }
      }
    }
  }

 private:
  static constexpr int kPad_px = 4;  // the halo's 3 px strokes reach past getTextSize's box
  struct Sprite {
    cv::Mat halo, ink;  // CV_8UC1 coverage, 0..255
    int above_px = 0;   // rows above the text's baseline origin
  };

  const Sprite& spriteOf(const std::string& text) {
    if (const auto found = sprites_.find(text); found != sprites_.end()) return found->second;
    if (sprites_.size() >= kMaxSprites) sprites_.clear();  // labels are few; bound them anyway
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, 0.4, 3, &baseline);
    Sprite sprite;
    sprite.above_px = size.height + kPad_px;
    const cv::Size box(size.width + 2 * kPad_px, size.height + baseline + 2 * kPad_px);
    const cv::Point origin(kPad_px, sprite.above_px);
    sprite.halo = cv::Mat::zeros(box, CV_8UC1);
    sprite.ink = cv::Mat::zeros(box, CV_8UC1);
    cv::putText(sprite.halo, text, origin, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(255), 3,
                cv::LINE_AA);
    cv::putText(sprite.ink, text, origin, cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(255), 1,
                cv::LINE_AA);
    return sprites_.emplace(text, std::move(sprite)).first->second;
  }

  static constexpr std::size_t kMaxSprites = 256;  // more than one slice shows (100 targets)
  std::unordered_map<std::string, Sprite> sprites_;
};

void drawScaleBar(cv::Mat& img, double pixel_mm, LabelCache& cache) {
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
    cache.draw(img, label.str(), {x0, y - 6}, white);
    return;
  }
}

void drawOrientation(cv::Mat& img, const Slice& slice, LabelCache& cache) {
  const EdgeLabels labels = orientationLabels(slice);
  const cv::Scalar colour(128, 255, 255);  // light yellow
  const int w = img.cols, h = img.rows;
  const cv::Size l = textSize(labels.left), r = textSize(labels.right), t = textSize(labels.top),
                 b = textSize(labels.bottom);
  cache.draw(img, labels.left, {3, h / 2 + l.height / 2}, colour);
  cache.draw(img, labels.right, {w - r.width - 3, h / 2 + r.height / 2}, colour);
  cache.draw(img, labels.top, {w / 2 - t.width / 2, t.height + 3}, colour);
  cache.draw(img, labels.bottom, {w / 2 - b.width / 2, h - 4}, colour);
}

}  // namespace

namespace {

// windowGrey's arithmetic, written so that the compiler vectorises the loop over a slice (no
// libm call; halves round up, as lround does for values >= 0). NaN must be handled before.
inline std::uint8_t greyOf(double value, double lo, double width) {
  double g = 255.0 * (value - lo) / width;
  g = g < 0.0 ? 0.0 : (g > 255.0 ? 255.0 : g);
  return static_cast<std::uint8_t>(g + 0.5);
}

}  // namespace

std::uint8_t windowGrey(double value, const WindowLevel& window) {
  if (std::isnan(value)) return 0;
  return greyOf(value, window.level - 0.5 * window.width, window.width);
}

namespace {

struct CompressorDeleter {
  void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};

}  // namespace

// Kept from one slice to the next; std::vector with UninitialisedAllocator grows without zeroing.
struct SliceRenderer::Buffers {
  cv::Mat canvas;
  std::vector<std::uint8_t, UninitialisedAllocator<std::uint8_t>> rows, stream;
  std::unique_ptr<libdeflate_compressor, CompressorDeleter> compressor;  // level 1, made once
  LabelCache labels;
};

SliceRenderer::SliceRenderer() : buffers_(std::make_unique<Buffers>()) {}
SliceRenderer::~SliceRenderer() = default;

Expected<std::vector<std::uint8_t>> SliceRenderer::renderPng(const Slice& slice,
                                                             const Overlays& overlays,
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
    cv::Mat& img = buffers_->canvas;
    img.create(slice.height, slice.width, CV_8UC3);
    const double lo = window.level - 0.5 * window.width;
    const Rgb out = options.outside;
    for (int v = 0; v < slice.height; ++v) {
      const float* in = &slice.values[static_cast<std::size_t>(v) * slice.width];
      std::uint8_t* row = img.ptr<std::uint8_t>(v);
      for (int u = 0; u < slice.width; ++u) {
        const double value = in[u];
        const bool outside = value != value;  // NaN: beyond the volume
        const std::uint8_t g = greyOf(outside ? lo : value, lo, window.width);
        row[3 * u] = outside ? out.b : g;  // BGR, as OpenCV draws
        row[3 * u + 1] = outside ? out.g : g;
        row[3 * u + 2] = outside ? out.r : g;
      }
    }
    for (const auto& region : overlays.regions) {
      const auto top = drawRegion(img, slice, region);
      // An outline's name just above and right of its topmost pixel, in its colour; below the
      // image's top edge when the outline reaches it (a structure cut by the view).
      if (top && !region.label.empty()) {
        const int baseline = std::max(top->y - 3, textSize(region.label).height + 2);
        buffers_->labels.draw(img, region.label, {top->x + 3, baseline}, bgr(region.colour));
      }
    }
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
        buffers_->labels.draw(img, point.label, {c.x + r + 3, c.y + 4}, bgr(point.colour));
      }
    }
    if (options.scale_bar) drawScaleBar(img, slice.pixel_size_mm, buffers_->labels);
    if (options.orientation_labels) drawOrientation(img, slice, buffers_->labels);

    return encodePngBgr(img.data, img.cols, img.rows, img.step[0]);
  } catch (const std::exception& e) {  // cv::Exception and bad_alloc must not cross the module
    return makeError(ErrorCode::kInternal, std::string("renderPng: ") + e.what());
  }
}

namespace {

void putBigEndian32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8)
    out.push_back(static_cast<std::uint8_t>(v >> shift));
}

// One PNG chunk: length, type, data, and the CRC-32 of type and data (PNG spec §5.3).
void putChunk(std::vector<std::uint8_t>& out, const char (&type)[5], const std::uint8_t* data,
              std::size_t size) {
  putBigEndian32(out, static_cast<std::uint32_t>(size));
  const std::size_t type_at = out.size();
  out.insert(out.end(), type, type + 4);
  out.insert(out.end(), data, data + size);
  putBigEndian32(out, libdeflate_crc32(0, out.data() + type_at, size + 4));
}

}  // namespace

// The PNG container (signature, IHDR, one IDAT, IEND) around a zlib stream from libdeflate's
// fastest level, rows unfiltered (issue 28: a slice goes to a viewer at every scroll step; with
// zlib's level 1 the encode was 90 % of a 512² slice's cost, docs/PERFORMANCE.md). The tests read
// these back with OpenCV's decoder (libpng underneath, which checks every CRC). Not OpenCV's
// imgcodecs: on Debian it links GDAL and ~120 libraries, 0.14 s at every program's start.
Expected<std::vector<std::uint8_t>> SliceRenderer::encodePngBgr(const std::uint8_t* bgr, int width,
                                                                int height,
                                                                std::size_t stride_bytes) {
  if (width <= 0 || height <= 0 || width > (1 << 24) || height > (1 << 24) ||
      stride_bytes < 3 * static_cast<std::size_t>(width)) {
    return makeError(ErrorCode::kInvalidArgument, "PNG: bad image size or stride");
  }
  const auto w = static_cast<std::size_t>(width), h = static_cast<std::size_t>(height);
  // The rows as PNG filters them (type 0, none: a leading 0 byte), in RGB order.
  const std::size_t row_bytes = 3 * w + 1;
  auto& raw = buffers_->rows;
  raw.resize(row_bytes * h);
  for (std::size_t y = 0; y < h; ++y) {
    const std::uint8_t* in = bgr + y * stride_bytes;
    std::uint8_t* out = raw.data() + y * row_bytes;
    out[0] = 0;
    for (std::size_t x = 0; x < w; ++x) {
      out[1 + 3 * x] = in[3 * x + 2];
      out[2 + 3 * x] = in[3 * x + 1];
      out[3 + 3 * x] = in[3 * x];
    }
  }
  auto& compressor = buffers_->compressor;
  if (!compressor) compressor.reset(libdeflate_alloc_compressor(1));  // ~700 KB of tables
  if (!compressor) return makeError(ErrorCode::kInternal, "PNG: libdeflate has no memory");
  auto& zlib = buffers_->stream;
  zlib.resize(libdeflate_zlib_compress_bound(compressor.get(), raw.size()));
  const std::size_t zlib_bytes =
      libdeflate_zlib_compress(compressor.get(), raw.data(), raw.size(), zlib.data(), zlib.size());
  if (zlib_bytes == 0) return makeError(ErrorCode::kInternal, "PNG: deflate failed (libdeflate)");

  std::vector<std::uint8_t> png;
  png.reserve(zlib_bytes + 64);
  static const std::uint8_t kSignature[8] = {137, 80, 78, 71, 13, 10, 26, 10};
  png.insert(png.end(), kSignature, kSignature + 8);
  std::vector<std::uint8_t> ihdr;
  putBigEndian32(ihdr, static_cast<std::uint32_t>(width));
  putBigEndian32(ihdr, static_cast<std::uint32_t>(height));
  // bit depth 8, colour type 2 (RGB), deflate, adaptive filtering method 0, no interlace
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});
  putChunk(png, "IHDR", ihdr.data(), ihdr.size());
  putChunk(png, "IDAT", zlib.data(), zlib_bytes);
  putChunk(png, "IEND", nullptr, 0);
  return png;
}

Expected<std::vector<std::uint8_t>> renderPng(const Slice& slice, const Overlays& overlays,
                                              const RenderOptions& options) {
  return SliceRenderer().renderPng(slice, overlays, options);
}

Expected<std::vector<std::uint8_t>> encodePngBgr(const std::uint8_t* bgr, int width, int height,
                                                 std::size_t stride_bytes) {
  return SliceRenderer().encodePngBgr(bgr, width, height, stride_bytes);
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
