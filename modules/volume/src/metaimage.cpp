// MetaImage reading (.mha with ElementDataFile = LOCAL, .mhd + raw), following ITK's MetaImageIO:
// geometry is LPS; TransformMatrix lists the direction of axis i as elements 3i..3i+2 (ITK's
// reader does SetDirection(i, {m[3i], m[3i+1], m[3i+2]})); AnatomicalOrientation is derived
// from the matrix by ITK's writer and ignored by its reader, so it is ignored here too.
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "header_text.hpp"
#include "ignav/volume/image_io.hpp"

namespace ignav::volume {
namespace {

using namespace header_text;  // NOLINT: the shared header-parsing helpers

namespace fs = std::filesystem;
using detail::ScalarType;

constexpr std::size_t kMaxHeaderBytes = std::size_t{1} << 20;

// Exactly `count` finite numbers separated by white space.
bool parseNumbers(const std::string& s, std::size_t count, std::vector<double>& out) {
  out.clear();
  const char* p = s.c_str();
  while (true) {
    while (std::isspace(static_cast<unsigned char>(*p)))
      ++p;
    if (*p == '\0') break;
    char* end = nullptr;
    const double v = std::strtod(p, &end);
    if (end == p || !std::isfinite(v)) return false;
    out.push_back(v);
    p = end;
  }
  return out.size() == count;
}

bool parseBool(const std::string& s, bool& out) {
  const std::string t = lower(s);
  if (t == "true" || t == "1") {
    out = true;
  } else if (t == "false" || t == "0") {
    out = false;
  } else {
    return false;
  }
  return true;
}

bool metaType(const std::string& name, ScalarType& t) {
  static const struct {
    const char* name;
    ScalarType type;
  } kTypes[] = {
      {"MET_CHAR", ScalarType::kInt8},   {"MET_UCHAR", ScalarType::kUInt8},
      {"MET_SHORT", ScalarType::kInt16}, {"MET_USHORT", ScalarType::kUInt16},
      {"MET_INT", ScalarType::kInt32},   {"MET_UINT", ScalarType::kUInt32},
      {"MET_FLOAT", ScalarType::kFloat}, {"MET_DOUBLE", ScalarType::kDouble},
  };
  for (const auto& entry : kTypes) {
    if (name == entry.name) {
      t = entry.type;
      return true;
    }
  }
  return false;
}

}  // namespace

Expected<Volume> readMetaImage(const std::string& path, const ProgressCallback& progress) {
  const std::string& what = path;
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(ErrorCode::kIo, what, "cannot open the file");

  // "Key = Value" lines up to and including ElementDataFile, which must come last.
  HeaderFields fields;
  std::string line;
  std::size_t header_bytes = 0;
  bool have_data_file = false;
  while (!have_data_file && readLine(in, line, 4096)) {
    header_bytes += line.size() + 1;
    if (header_bytes > kMaxHeaderBytes) {
      return fail(ErrorCode::kFormat, what, "header longer than 1 MiB");
    }
    const std::string t = trim(line);
    if (t.empty()) continue;
    const auto eq = t.find('=');
    if (eq == std::string::npos || eq == 0) {
      return fail(ErrorCode::kFormat, what,
                  "not a MetaImage header line: '" + printable(t) + "' (expected Key = Value)");
    }
    std::string key = lower(trim(t.substr(0, eq)));
    fields.add(key, trim(t.substr(eq + 1)));
    have_data_file = key == "elementdatafile";
  }
  if (!have_data_file) {
    return fail(ErrorCode::kFormat, what, "missing field 'ElementDataFile' (truncated header?)");
  }

  if (const std::string* object = fields.find({"objecttype"});
      object != nullptr && lower(*object) != "image") {
    return fail(ErrorCode::kUnsupported, what, "ObjectType '" + *object + "' is not Image");
  }
  const std::string* ndims = fields.find({"ndims"});
  if (ndims == nullptr) return missingField(what, "NDims");
  if (trim(*ndims) != "3") {
    return fail(ErrorCode::kUnsupported, what, "NDims " + *ndims + " (only 3D volumes)");
  }
  if (const std::string* channels = fields.find({"elementnumberofchannels"});
      channels != nullptr && trim(*channels) != "1") {
    return fail(ErrorCode::kUnsupported, what,
                "ElementNumberOfChannels " + *channels + " (only scalar volumes)");
  }
  if (const std::string* binary = fields.find({"binarydata"})) {
    bool b = true;
    if (!parseBool(*binary, b)) {
      return fail(ErrorCode::kFormat, what, "BinaryData '" + *binary + "' is not True/False");
    }
    if (!b) return fail(ErrorCode::kUnsupported, what, "ASCII data (BinaryData = False)");
  }

  Volume volume;
  Geometry& g = volume.geometry;
  std::vector<double> nums;
  const std::string* dim_size = fields.find({"dimsize"});
  if (dim_size == nullptr) return missingField(what, "DimSize");
  if (!parseNumbers(*dim_size, 3, nums)) {
    return fail(ErrorCode::kFormat, what, "DimSize '" + *dim_size + "' must hold 3 integers");
  }
  for (std::size_t a = 0; a < 3; ++a) {
    if (nums[a] != std::floor(nums[a]) || nums[a] < 1.0 ||
        nums[a] > std::numeric_limits<int>::max()) {
      return fail(ErrorCode::kFormat, what,
                  "DimSize '" + *dim_size + "' must hold 3 positive integers");
    }
    g.dims[a] = static_cast<int>(nums[a]);
  }
  if (const std::string* spacing = fields.find({"elementspacing", "elementsize"})) {
    if (!parseNumbers(*spacing, 3, nums)) {
      return fail(ErrorCode::kFormat, what,
                  "ElementSpacing '" + *spacing + "' must hold 3 numbers");
    }
    g.spacing_mm = Eigen::Vector3d(nums[0], nums[1], nums[2]);
  }
  if (const std::string* origin = fields.find({"offset", "position", "origin"})) {
    if (!parseNumbers(*origin, 3, nums)) {
      return fail(ErrorCode::kFormat, what, "Offset '" + *origin + "' must hold 3 numbers");
    }
    g.origin_lps_mm = Eigen::Vector3d(nums[0], nums[1], nums[2]);
  }
  if (const std::string* matrix = fields.find({"transformmatrix", "rotation", "orientation"})) {
    if (!parseNumbers(*matrix, 9, nums)) {
      return fail(ErrorCode::kFormat, what,
                  "TransformMatrix '" + *matrix + "' must hold 9 numbers");
    }
    for (int axis = 0; axis < 3; ++axis) {
      for (int r = 0; r < 3; ++r)
        g.direction(r, axis) = nums[static_cast<std::size_t>(3 * axis + r)];
    }
  }
  if (auto s = g.validate(what); !s.ok()) return s.error();

  detail::RasterSource source;
  const std::string* type_name = fields.find({"elementtype"});
  if (type_name == nullptr) return missingField(what, "ElementType");
  if (!metaType(*type_name, source.type)) {
    return fail(ErrorCode::kUnsupported, what, "ElementType '" + *type_name + "' is not supported");
  }
  if (const std::string* msb = fields.find({"binarydatabyteordermsb", "elementbyteordermsb"})) {
    if (!parseBool(*msb, source.big_endian)) {
      return fail(ErrorCode::kFormat, what,
                  "BinaryDataByteOrderMSB '" + *msb + "' is not True/False");
    }
  }
  if (const std::string* comp = fields.find({"compresseddata"})) {
    if (!parseBool(*comp, source.compressed)) {
      return fail(ErrorCode::kFormat, what, "CompressedData '" + *comp + "' is not True/False");
    }
  }
  const std::string data_file = *fields.find({"elementdatafile"});
  if (data_file == "LOCAL" || lower(data_file) == "local") {
    source.data_path = path;
    source.byte_skip = static_cast<std::int64_t>(in.tellg());
    if (source.byte_skip < 0) {
      return fail(ErrorCode::kFormat, what, "no data follows 'ElementDataFile = LOCAL'");
    }
  } else {
    if (data_file.empty() || data_file.rfind("LIST", 0) == 0 ||
        data_file.find('%') != std::string::npos) {
      return fail(ErrorCode::kUnsupported, what,
                  "ElementDataFile '" + data_file + "': only LOCAL or a single file is supported");
    }
    fs::path p(data_file);
    if (p.is_relative()) p = fs::path(path).parent_path() / p;
    source.data_path = p.string();
    if (const std::string* hs = fields.find({"headersize"})) {
      char* end = nullptr;
      errno = 0;
      const long long v = std::strtoll(hs->c_str(), &end, 10);
      if (errno != 0 || end == hs->c_str() || *end != '\0' || v < -1) {
        return fail(ErrorCode::kFormat, what, "HeaderSize '" + *hs + "' is invalid");
      }
      source.byte_skip = v;
    }
  }
  in.close();
  if (auto s = detail::readRaster(source, what, progress, volume); !s.ok()) return s.error();
  volume.description = fs::path(path).filename().string();
  return volume;
}

}  // namespace ignav::volume
