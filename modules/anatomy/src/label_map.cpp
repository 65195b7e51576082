// A label map with a 3D Slicer colour table naming its labels (structures.hpp).
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "ignav/anatomy/structures.hpp"
#include "ignav/volume/image_io.hpp"

namespace ignav::anatomy {
namespace {

struct Entry {
  std::string name;
  std::array<double, 3> rgb{0.5, 0.5, 0.5};
};

// Slicer's colour table: "LABEL NAME R G B A" per line (0-255), '#' comments.
Expected<std::map<int, Entry>> readColourTable(const std::string& path) {
  std::ifstream in(path);
  if (!in) return makeError(ErrorCode::kIo, path + ": cannot open the colour table", "io");
  std::map<int, Entry> out;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream words(line);
    long label = 0;
    Entry e;
    int rgb[3] = {128, 128, 128};
    if (!(words >> label >> e.name)) {
      return makeError(ErrorCode::kFormat,
                       fmt::format("{} line {}: '{}' is not 'LABEL NAME R G B A'", path, n, line),
                       "names_missing");
    }
    if (label < 0 || label > 32767) {
      return makeError(ErrorCode::kFormat,
                       fmt::format("{} line {}: label {} is outside 0-32767", path, n, label),
                       "label_out_of_range");
    }
    if (words >> rgb[0] >> rgb[1] >> rgb[2]) {
      for (int c = 0; c < 3; ++c) {
        if (rgb[c] < 0 || rgb[c] > 255) {
          return makeError(ErrorCode::kFormat,
                           fmt::format("{} line {}: colour {} is outside 0-255", path, n, rgb[c]));
        }
        e.rgb[static_cast<std::size_t>(c)] = rgb[c] / 255.0;
      }
    }
    if (out.count(static_cast<int>(label))) {
      return makeError(ErrorCode::kFormat,
                       fmt::format("{} line {}: label {} is named twice", path, n, label));
    }
    out[static_cast<int>(label)] = e;
  }
  return out;
}

}  // namespace

Expected<StructureSet> readLabelMap(const std::string& path, const std::string& colour_table) {
  auto table = readColourTable(colour_table);
  if (!table) return table.error();
  auto image = volume::readVolumeFile(path);
  if (!image) return image.error();
  const auto& v = *image;
  std::map<int, std::vector<std::uint8_t>> labels;  // label -> its voxels
  for (std::size_t n = 0; n < v.voxels.size(); ++n) {
    const double value = v.voxels[n] * v.value_scale + v.value_offset;
    if (value == 0.0) continue;
    if (value != std::round(value) || value < 1.0 || value > 32767.0) {
      return makeError(ErrorCode::kFormat,
                       fmt::format("{}: voxel {} holds {} (labels are integers 1-32767, 0 the "
                                   "background)",
                                   path, n, value),
                       "label_out_of_range");
    }
    auto& mask = labels[static_cast<int>(value)];
    if (mask.empty()) mask.assign(v.voxels.size(), 0);
    mask[n] = 1;
  }
  if (labels.empty()) {
    return makeError(ErrorCode::kFormat, path + ": every voxel is background (0): no structure",
                     "empty_structure");
  }
  StructureSet set;
  set.source = path;
  for (const auto& [label, inside] : labels) {
    const auto e = table->find(label);
    if (e == table->end() || label == 0) {
      return makeError(ErrorCode::kFormat,
                       fmt::format("{}: label {} is not named in {}", path, label, colour_table),
                       "names_missing");
    }
    if (set.find(e->second.name)) {
      return makeError(ErrorCode::kFormat,
                       fmt::format("{}: two labels are named '{}'", colour_table, e->second.name));
    }
    auto mask = cropMask(v.geometry, inside, fmt::format("{}: label {}", path, label));
    if (!mask) return mask.error();
    Structure s;
    s.name = e->second.name;
    s.colour_rgb = e->second.rgb;
    s.mask = std::move(mask).value();
    set.structures.push_back(std::move(s));
  }
  return set;
}

}  // namespace ignav::anatomy
