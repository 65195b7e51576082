#include "ignav/volume/threshold.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ignav::volume {
namespace {

// Plain reductions the compiler vectorises (this file is built with GCC's dynamic cost model).
std::int16_t blockMax(const std::int16_t* v, std::size_t n) {
  std::int16_t m = std::numeric_limits<std::int16_t>::min();
  for (std::size_t i = 0; i < n; ++i)
    m = v[i] > m ? v[i] : m;
  return m;
}

std::int16_t blockMin(const std::int16_t* v, std::size_t n) {
  std::int16_t m = std::numeric_limits<std::int16_t>::max();
  for (std::size_t i = 0; i < n; ++i)
    m = v[i] < m ? v[i] : m;
  return m;
}

}  // namespace

Expected<std::vector<std::uint32_t>> voxelsAtOrAbove(const Volume& volume, double min_hu,
                                                     std::size_t max_count) {
  std::vector<std::uint32_t> bright;
  if (volume.value_scale == 0.0 || !std::isfinite(volume.value_scale) ||
      !std::isfinite(volume.value_offset)) {
    return makeError(ErrorCode::kInvalidArgument, "volume: value scale 0 or not finite");
  }
  // The threshold in stored units: the pass is an int16 compare.
  const double stored = (min_hu - volume.value_offset) / volume.value_scale;
  const bool rising = volume.value_scale > 0.0;  // a larger stored value is brighter
  const double bound = rising ? std::ceil(stored) : std::floor(stored);
  if (rising ? bound > 32767.0 : bound < -32768.0) return bright;  // nothing can reach it
  const auto limit = static_cast<std::int16_t>(std::clamp(bound, -32768.0, 32767.0));
  const std::int16_t* data = volume.voxels.data();
  const std::size_t total = volume.voxels.size();  // ≤ kMaxVoxels: an index fits 32 bits
  constexpr std::size_t kBlock = 4096;
  for (std::size_t start = 0; start < total; start += kBlock) {
    const std::size_t end = std::min(total, start + kBlock);
    if (rising ? blockMax(data + start, end - start) < limit
               : blockMin(data + start, end - start) > limit) {
      continue;
    }
    for (std::size_t idx = start; idx < end; ++idx) {
      if (rising ? data[idx] < limit : data[idx] > limit) continue;
      if (bright.size() == max_count) {
        return Error{ErrorCode::kInvalidArgument,
                     "more than " + std::to_string(max_count) + " voxels at or above the threshold",
                     "too_many_bright_voxels"};
      }
      bright.push_back(static_cast<std::uint32_t>(idx));
    }
  }
  return bright;
}

}  // namespace ignav::volume
