// 3D Slicer's segmentation files (.seg.nrrd): binary labelmap layers with Segment<N>_* fields
// (Slicer's vtkSegmentationStorageNode). Slicer 4.11+ writes Segment<N>_LabelValue and _Layer;
// older files keep one segment per layer with label 1, which is what their absence means.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "ignav/anatomy/site.hpp"
#include "ignav/anatomy/structures.hpp"
#include "ignav/volume/image_io.hpp"

namespace ignav::anatomy {
namespace {

Error bad(const std::string& path, const std::string& what, const char* reason = "bad_segment") {
  return makeError(ErrorCode::kFormat, path + ": " + what, reason);
}

bool parseInt(const std::string& s, long& out) {
  std::istringstream in(s);
  return (in >> out) && (in >> std::ws).eof();
}

// "ignav.role:avoid|ignav.margin_mm:3|" (Slicer's tag list) -> the tags.
std::map<std::string, std::string> tags(const std::string& text) {
  std::map<std::string, std::string> out;
  std::istringstream in(text);
  std::string item;
  while (std::getline(in, item, '|')) {
    const auto colon = item.find(':');
    if (colon != std::string::npos) out[item.substr(0, colon)] = item.substr(colon + 1);
  }
  return out;
}

}  // namespace

Expected<StructureSet> readSegNrrd(const std::string& path) {
  auto image = volume::readNrrdLayers(path);
  if (!image) return image.error();
  std::map<std::string, std::string> fields(image->key_values.begin(), image->key_values.end());
  auto field = [&](int n, const char* key) -> const std::string* {
    const auto it = fields.find(fmt::format("Segment{}_{}", n, key));
    return it == fields.end() ? nullptr : &it->second;
  };
  StructureSet set;
  set.source = path;
  const auto& g = image->geometry;
  const std::size_t voxels = g.voxelCount();
  const int layers = image->components;
  std::vector<std::pair<int, int>> described;  // (layer, label) of each segment
  for (int n = 0; field(n, "ID") || field(n, "Name") || field(n, "LabelValue"); ++n) {
    const std::string seg = fmt::format("segment {}", n);
    const std::string* name = field(n, "Name");
    if (!name || name->empty()) {
      return bad(path, fmt::format("{} has no name (Segment{}_Name)", seg, n), "names_missing");
    }
    const std::string what = fmt::format("segment {} '{}'", n, *name);
    if (set.find(*name)) return bad(path, fmt::format("two segments are named '{}'", *name));
    long label = 1, layer = layers > 1 ? n : 0;
    if (const auto* v = field(n, "LabelValue");
        v && (!parseInt(*v, label) || label < 1 || label > 32767)) {
      return bad(path, fmt::format("{}: label value '{}' is not an integer in 1-32767", what, *v),
                 "label_out_of_range");
    }
    if (const auto* v = field(n, "Layer"); v && (!parseInt(*v, layer) || layer < 0)) {
      return bad(path, fmt::format("{}: layer '{}' is not a count", what, *v));
    }
    if (layer >= layers) {
      return bad(path,
                 fmt::format("{}: layer {} does not exist (the file has {})", what, layer, layers),
                 "label_out_of_range");
    }
    described.emplace_back(static_cast<int>(layer), static_cast<int>(label));
    Structure s;
    s.name = *name;
    if (const auto* c = field(n, "Color")) {
      std::istringstream in(*c);
      for (auto& v : s.colour_rgb) {
        if (!(in >> v) || !(v >= 0.0 && v <= 1.0)) {
          return bad(path, fmt::format("{}: colour '{}' is not three numbers in 0-1", what, *c));
        }
      }
    }
    if (const auto* t = field(n, "Tags")) {
      const auto tag = tags(*t);
      if (const auto it = tag.find("ignav.role"); it != tag.end()) {
        const auto role = roleNamed(it->second);
        if (!role) return bad(path, fmt::format("{}: role '{}' is unknown", what, it->second));
        s.role = *role;
      }
      if (const auto it = tag.find("ignav.margin_mm"); it != tag.end()) {
        char* end = nullptr;
        s.margin_mm = std::strtod(it->second.c_str(), &end);
        if (end == it->second.c_str() || *end != '\0' || !std::isfinite(s.margin_mm) ||
            s.margin_mm < 0.0) {
          return bad(path, fmt::format("{}: margin '{}' is not a distance", what, it->second));
        }
        // As a site file or structure_role would have it: a wider margin is no margin but a ban.
        if (s.margin_mm > kMaxMargin_mm) {
          return bad(path, fmt::format("{}: margin {:g} mm is outside 0-{:g} mm", what, s.margin_mm,
                                       kMaxMargin_mm));
        }
      }
    }
    std::vector<std::uint8_t> inside(voxels, 0);
    for (std::size_t v = 0; v < voxels; ++v)
      inside[v] =
          image->values[v * static_cast<std::size_t>(layers) + static_cast<std::size_t>(layer)] ==
          label;
    auto mask = cropMask(g, inside, path + ": " + what);
    if (!mask) return mask.error();
    s.mask = std::move(mask).value();
    set.structures.push_back(std::move(s));
  }
  if (set.structures.empty()) {
    return bad(path, "no segment is described (no Segment0_ID / Segment0_Name field)",
               "names_missing");
  }
  // Labels no segment names: a file edited by hand, or a segment whose fields were lost.
  for (std::size_t v = 0; v < image->values.size(); ++v) {
    const int label = image->values[v];
    const auto layer = static_cast<int>(v % static_cast<std::size_t>(layers));
    if (label != 0 && !std::count(described.begin(), described.end(), std::pair(layer, label))) {
      return bad(path,
                 fmt::format("label {} in layer {} belongs to no segment (voxel {})", label, layer,
                             v / static_cast<std::size_t>(layers)),
                 "label_out_of_range");
    }
  }
  return set;
}

Status writeSegNrrd(const StructureSet& set, const volume::Geometry& grid,
                    const std::string& path) {
  if (set.structures.empty() || set.structures.size() > 255) {
    return makeError(ErrorCode::kInvalidArgument, path + ": 1 to 255 structures are written");
  }
  // Every mask's first voxel on the grid; the file covers their union (Slicer crops so too, and
  // says where with Segmentation_ReferenceImageExtentOffset).
  std::vector<Eigen::Vector3i> first;
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(std::numeric_limits<int>::max());
  Eigen::Vector3i hi = Eigen::Vector3i::Constant(std::numeric_limits<int>::min());
  for (const auto& s : set.structures) {
    const Eigen::Vector3d at = grid.toIjk(s.mask.geometry.origin_lps_mm);
    const Eigen::Vector3i f = at.array().round().cast<int>();
    if ((at - f.cast<double>()).cwiseAbs().maxCoeff() > 0.01 ||
        (s.mask.geometry.spacing_mm - grid.spacing_mm).cwiseAbs().maxCoeff() > 1e-6) {
      return makeError(ErrorCode::kInvalidArgument,
                       path + ": structure '" + s.name + "' is not on the grid written");
    }
    first.push_back(f);
    const auto& d = s.mask.geometry.dims;
    lo = lo.cwiseMin(f);
    hi = hi.cwiseMax(f + Eigen::Vector3i(d[0] - 1, d[1] - 1, d[2] - 1));
  }
  volume::NrrdLayers image;
  image.geometry = grid;
  for (int a = 0; a < 3; ++a)
    image.geometry.dims[static_cast<std::size_t>(a)] = hi[a] - lo[a] + 1;
  image.geometry.origin_lps_mm = grid.toLps(lo.cast<double>());
  // Layers: each structure in the first layer where it overlaps none before it.
  const auto& out = image.geometry.dims;
  const std::size_t voxels = image.geometry.voxelCount();
  std::vector<std::vector<std::uint8_t>> layer_labels;
  std::vector<std::pair<int, int>> placed;  // (layer, label) per structure
  for (std::size_t n = 0; n < set.structures.size(); ++n) {
    const auto& m = set.structures[n].mask;
    const Eigen::Vector3i off = first[n] - lo;
    std::vector<std::size_t> at;
    for (int k = 0; k < m.geometry.dims[2]; ++k)
      for (int j = 0; j < m.geometry.dims[1]; ++j)
        for (int i = 0; i < m.geometry.dims[0]; ++i)
          if (m.inside[m.index(i, j, k)])
            at.push_back(gridIndex(out, i + off.x(), j + off.y(), k + off.z()));
    std::size_t layer = 0;
    for (; layer < layer_labels.size(); ++layer) {
      const auto& l = layer_labels[layer];
      if (std::none_of(at.begin(), at.end(), [&](std::size_t v) { return l[v] != 0; })) break;
    }
    if (layer == layer_labels.size()) layer_labels.emplace_back(voxels, 0);
    int label = 1;
    for (const auto& [y, l] : placed)
      if (y == static_cast<int>(layer)) label = std::max(label, l + 1);
    for (const auto v : at)
      layer_labels[layer][v] = static_cast<std::uint8_t>(label);
    placed.emplace_back(static_cast<int>(layer), label);
  }
  image.components = static_cast<int>(layer_labels.size());
  image.values.resize(voxels * layer_labels.size());
  for (std::size_t v = 0; v < voxels; ++v)
    for (std::size_t y = 0; y < layer_labels.size(); ++y)
      image.values[v * layer_labels.size() + y] = layer_labels[y][v];
  auto& kv = image.key_values;
  for (std::size_t n = 0; n < set.structures.size(); ++n) {
    const auto& s = set.structures[n];
    const auto key = [n](const char* k) { return fmt::format("Segment{}_{}", n, k); };
    const auto& d = s.mask.geometry.dims;
    const Eigen::Vector3i f = first[n] - lo;
    kv.emplace_back(key("Color"), fmt::format("{:.6g} {:.6g} {:.6g}", s.colour_rgb[0],
                                              s.colour_rgb[1], s.colour_rgb[2]));
    kv.emplace_back(key("ColorAutoGenerated"), "0");
    kv.emplace_back(key("Extent"), fmt::format("{} {} {} {} {} {}", f.x(), f.x() + d[0] - 1, f.y(),
                                               f.y() + d[1] - 1, f.z(), f.z() + d[2] - 1));
    kv.emplace_back(key("ID"), s.name);
    kv.emplace_back(key("LabelValue"), std::to_string(placed[n].second));
    kv.emplace_back(key("Layer"), std::to_string(placed[n].first));
    kv.emplace_back(key("Name"), s.name);
    kv.emplace_back(key("NameAutoGenerated"), "0");
    kv.emplace_back(key("Tags"), fmt::format("ignav.role:{}|ignav.margin_mm:{:g}|",
                                             toString(s.role), s.margin_mm));
  }
  kv.emplace_back("Segmentation_ContainedRepresentationNames", "Binary labelmap|");
  kv.emplace_back("Segmentation_MasterRepresentation", "Binary labelmap");
  kv.emplace_back("Segmentation_ReferenceImageExtentOffset",
                  fmt::format("{} {} {}", lo.x(), lo.y(), lo.z()));
  return volume::writeNrrdLayers(image, path);
}

}  // namespace ignav::anatomy
