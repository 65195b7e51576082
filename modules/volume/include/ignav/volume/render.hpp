// Slices to 8-bit PNG with window/level and navigation overlays (points, paths, the robot's
// feasible region, scale bar, orientation labels). OpenCV stays inside src/.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/volume/slice.hpp"

namespace ignav::volume {

struct Rgb {
  std::uint8_t r = 255, g = 255, b = 255;
};

// A point drawn filled when within the in-plane tolerance of the slice, else as a hollow ring.
struct PointMarker {
  Eigen::Vector3d lps_mm = Eigen::Vector3d::Zero();
  std::string label;  // drawn to the right of the marker; "" for none
  Rgb colour{255, 255, 0};
  int radius_px = 4;
};

struct PathOverlay {
  std::vector<Eigen::Vector3d> lps_mm;  // projected onto the slice and joined in order
  Rgb colour{0, 255, 255};
  int thickness_px = 1;
};

// Tinted translucently where `contains(lps)` holds (evaluated at every pixel centre) and/or
// inside `polygon_lps_mm` (projected onto the slice).
struct RegionOverlay {
  std::function<bool(const Eigen::Vector3d& lps_mm)> contains;
  // When given: points (LPS mm) whose convex hull holds every point where contains() holds, so
  // that contains() is asked only inside their box on the slice, and not at all on a slice that
  // misses them.
  std::vector<Eigen::Vector3d> bounds_lps_mm;
  std::vector<Eigen::Vector3d> polygon_lps_mm;
  Rgb colour{0, 255, 0};
  double opacity = 0.3;
  // contains() drawn as its outline only (the pixels inside with a neighbour outside), as
  // segmentations are shown over a CT.
  bool outline = false;
  std::string label{};  // an outline's name, drawn by its topmost pixel; "" for none
};

struct Overlays {
  std::vector<RegionOverlay> regions;  // drawn first, then paths, then points
  std::vector<PathOverlay> paths;
  std::vector<PointMarker> points;
};

struct RenderOptions {
  std::optional<WindowLevel> window;   // default: the slice's own
  double in_plane_tolerance_mm = 0.0;  // 0: half the slice thickness
  bool scale_bar = true;               // bottom left, a round length near 1/4 of the width
  bool orientation_labels = true;
  Rgb outside{0, 0, 0};  // pixels beyond the volume (NaN)
};

// Grey level of a physical value: 255 * (value - (level - width/2)) / width, rounded, clamped.
std::uint8_t windowGrey(double value, const WindowLevel& window);  // NaN: 0

// Draws a slice with its overlays and encodes it as PNG (libdeflate's fastest level, rows
// unfiltered), keeping its buffers from one slice to the next: the canvas, the PNG's rows and
// stream, the compressor. Fresh ones cost a page fault per 4 KiB and zeroing, as much as the
// encoding itself on a VM (issue 28). One for a thread that draws at every scroll step (the
// server's slices thread); not to be used by two threads at once.
class SliceRenderer {
 public:
  SliceRenderer();
  ~SliceRenderer();
  SliceRenderer(const SliceRenderer&) = delete;
  SliceRenderer& operator=(const SliceRenderer&) = delete;

  Expected<std::vector<std::uint8_t>> renderPng(const Slice& slice, const Overlays& overlays = {},
                                                const RenderOptions& options = {});
  // PNG bytes of an 8-bit BGR image (rows `stride_bytes` apart).
  Expected<std::vector<std::uint8_t>> encodePngBgr(const std::uint8_t* bgr, int width, int height,
                                                   std::size_t stride_bytes);

 private:
  struct Buffers;  // OpenCV and libdeflate stay inside src/
  std::unique_ptr<Buffers> buffers_;
};

// The same with buffers of its own, for a picture now and then.
Expected<std::vector<std::uint8_t>> renderPng(const Slice& slice, const Overlays& overlays = {},
                                              const RenderOptions& options = {});
Status writePng(const std::vector<std::uint8_t>& png, const std::string& path);

// PNG bytes of an 8-bit BGR image (rows `stride_bytes` apart), for other figures we draw.
Expected<std::vector<std::uint8_t>> encodePngBgr(const std::uint8_t* bgr, int width, int height,
                                                 std::size_t stride_bytes);

}  // namespace ignav::volume
