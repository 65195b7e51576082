// NRRD reading and writing (http://teem.sourceforge.net/nrrd/format.html), as 3D Slicer uses it,
// and the raster decoding shared with the MetaImage reader.
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <limits>
#include <new>
#include <sstream>

#include "header_text.hpp"
#include "ignav/volume/image_io.hpp"

namespace ignav::volume {
namespace {

using namespace header_text;  // NOLINT: the shared header-parsing helpers

namespace fs = std::filesystem;
using detail::ScalarType;

constexpr std::size_t kChunkBytes = std::size_t{16} << 20;  // progress and I/O granularity
constexpr std::size_t kMaxHeaderBytes = std::size_t{1} << 20;
// Deflate cannot expand more than ~1032:1, so a header declaring more than that is a lie.
constexpr std::uint64_t kMaxInflateRatio = 1040;

std::size_t sizeOf(ScalarType t) {
  switch (t) {
    case ScalarType::kInt8:
    case ScalarType::kUInt8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUInt16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUInt32:
    case ScalarType::kFloat:
      return 4;
    case ScalarType::kDouble:
      return 8;
  }
  return 1;
}

bool hostIsBigEndian() {
  const std::uint16_t one = 1;
  unsigned char first = 0;
  std::memcpy(&first, &one, 1);
  return first == 0;
}

void swapBytes(std::uint8_t* data, std::size_t bytes, std::size_t width) {
  if (width < 2) return;
  for (std::size_t i = 0; i + width <= bytes; i += width)
    std::reverse(data + i, data + i + width);
}

void report(const ProgressCallback& progress, std::size_t done, std::size_t total) {
  if (progress) progress(Progress{"decode", done, total});
}

// Reads exactly `bytes` raw bytes from `in` into dst.
Status readRaw(std::ifstream& in, std::uint8_t* dst, std::size_t bytes, const std::string& what,
               const ProgressCallback& progress) {
  std::size_t done = 0;
  while (done < bytes) {
    const std::size_t n = std::min(kChunkBytes, bytes - done);
    in.read(reinterpret_cast<char*>(dst + done), static_cast<std::streamsize>(n));
    const auto got = static_cast<std::size_t>(in.gcount());
    done += got;
    if (got != n) {
      return fail(ErrorCode::kFormat, what,
                  "data shorter than declared: read " + std::to_string(done) + " of " +
                      std::to_string(bytes) + " bytes");
    }
    report(progress, done, bytes);
  }
  return Ok{};
}

// Inflates a zlib or gzip stream (concatenated gzip members too) into exactly `bytes`.
Status inflateAll(std::ifstream& in, std::uint8_t* dst, std::size_t bytes, const std::string& what,
                  const ProgressCallback& progress) {
  z_stream zs{};
  if (inflateInit2(&zs, 15 + 32) != Z_OK) {  // 15 + 32: detect zlib or gzip header
    return fail(ErrorCode::kInternal, what, "zlib inflateInit2 failed");
  }
  std::vector<char> input(std::size_t{1} << 20);
  std::size_t done = 0;
  std::size_t last_report = 0;
  bool stream_end = false;
  Status result = Ok{};
  while (done < bytes) {
    if (zs.avail_in == 0) {
      in.read(input.data(), static_cast<std::streamsize>(input.size()));
      const auto got = static_cast<uInt>(in.gcount());
      if (got == 0) break;  // input exhausted
      zs.next_in = reinterpret_cast<Bytef*>(input.data());
      zs.avail_in = got;
      if (stream_end) {  // another gzip member follows
        inflateReset(&zs);
        stream_end = false;
      }
    }
    const std::size_t want = std::min<std::size_t>(bytes - done, std::size_t{1} << 30);
    zs.next_out = dst + done;
    zs.avail_out = static_cast<uInt>(want);
    const int rc = inflate(&zs, Z_NO_FLUSH);
    done += want - zs.avail_out;
    if (rc == Z_STREAM_END) {
      stream_end = true;
      if (zs.avail_in > 0 && done < bytes) {
        inflateReset(&zs);
        stream_end = false;
      }
    } else if (rc == Z_BUF_ERROR && zs.avail_in == 0) {
      continue;  // needs more input
    } else if (rc != Z_OK) {
      result = fail(ErrorCode::kFormat, what,
                    std::string("compressed data is corrupt (zlib: ") +
                        (zs.msg != nullptr ? zs.msg : "error " + std::to_string(rc)) + ")");
      break;
    }
    if (done - last_report >= kChunkBytes) {
      report(progress, done, bytes);
      last_report = done;
    }
  }
  inflateEnd(&zs);
  if (!result.ok()) return result;
  if (done < bytes) {
    return fail(ErrorCode::kFormat, what,
                "data shorter than declared: decompressed " + std::to_string(done) + " of " +
                    std::to_string(bytes) + " bytes");
  }
  report(progress, done, bytes);
  return Ok{};
}

template <typename T>
T load(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

// Maps integers in [lo, hi] to int16 exactly, or says why not.
Status integerMapping(std::int64_t lo, std::int64_t hi, const std::string& what, ScalarType type,
                      Volume& volume, std::int64_t& shift) {
  if (lo >= -32768 && hi <= 32767) {
    shift = 0;
  } else if (hi - lo <= 65535) {
    shift = lo + 32768;  // stored = value - shift fills int16 from its minimum
  } else {
    return fail(ErrorCode::kUnsupported, what,
                std::string("voxel type ") + detail::toString(type) + " with values from " +
                    std::to_string(lo) + " to " + std::to_string(hi) +
                    " spans more than the 65536 levels of int16; convert it to int16 first");
  }
  volume.value_scale = 1.0;
  volume.value_offset = static_cast<double>(shift);
  return Ok{};
}

template <typename T>
Status convertInteger(const std::uint8_t* src, std::size_t n, const std::string& what,
                      ScalarType type, Volume& volume) {
  std::int64_t lo = std::numeric_limits<std::int64_t>::max();
  std::int64_t hi = std::numeric_limits<std::int64_t>::min();
  for (std::size_t i = 0; i < n; ++i) {
    const auto v = static_cast<std::int64_t>(load<T>(src + i * sizeof(T)));
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  std::int64_t shift = 0;
  if (auto s = integerMapping(lo, hi, what, type, volume, shift); !s.ok()) return s;
  volume.voxels.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    volume.voxels[i] =
        static_cast<std::int16_t>(static_cast<std::int64_t>(load<T>(src + i * sizeof(T))) - shift);
  }
  return Ok{};
}

// Floating data is accepted only when it is exactly k * step + v_min with k < 65536 (integers,
// or a rescaled integer image such as writeNrrd's own double output).
template <typename T>
Status convertFloating(const std::uint8_t* src, std::size_t n, const std::string& what,
                       ScalarType type, Volume& volume) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  bool integral = true;
  for (std::size_t i = 0; i < n; ++i) {
    const double v = static_cast<double>(load<T>(src + i * sizeof(T)));
    if (!std::isfinite(v)) {
      return fail(ErrorCode::kFormat, what,
                  "voxel " + std::to_string(i) + " is not a finite number");
    }
    lo = std::min(lo, v);
    hi = std::max(hi, v);
    integral = integral && v == std::floor(v);
  }
  if (integral && lo >= -9e15 && hi <= 9e15) {
    std::int64_t shift = 0;
    if (integerMapping(static_cast<std::int64_t>(lo), static_cast<std::int64_t>(hi), what, type,
                       volume, shift)
            .ok()) {
      volume.voxels.resize(n);
      for (std::size_t i = 0; i < n; ++i) {
        volume.voxels[i] = static_cast<std::int16_t>(
            static_cast<std::int64_t>(static_cast<double>(load<T>(src + i * sizeof(T)))) - shift);
      }
      return Ok{};
    }
  }
  // The step is the greatest common divisor of all rises above the minimum (Euclid with a
  // tolerance for the type's rounding); more than 65535 steps means the data is not a grid.
  const double rel_eps = sizeof(T) == 4 ? 1e-6 : 1e-9;
  const double tol = rel_eps * std::max({std::abs(lo), std::abs(hi), hi - lo});
  const std::string why = std::string("voxel type ") + detail::toString(type) +
                          " whose values are not on a grid of at most 65536 levels is not " +
                          "supported (it would have to be rounded); convert it to int16 first";
  double step = 0.0;
  const double min_step = (hi - lo) / 65535.0;
  for (std::size_t i = 0; i < n; ++i) {
    double b = static_cast<double>(load<T>(src + i * sizeof(T))) - lo;
    double a = step;
    while (b > tol) {
      double r = std::fmod(a, b);
      if (r < tol || b - r < tol) r = 0.0;
      a = b;
      b = r;
    }
    step = a;
    if (step > 0.0 && step < min_step * (1.0 - 1e-9))
      return fail(ErrorCode::kUnsupported, what, why);
  }
  double levels = 0.0;
  if (step > 0.0) {
    levels = std::round((hi - lo) / step);
    if (levels > 65535.0) return fail(ErrorCode::kUnsupported, what, why);
    step = (hi - lo) / levels;
  } else {
    step = 1.0;  // constant image
  }
  const double base = levels > 32767.0 ? lo + 32768.0 * step : lo;
  volume.value_scale = step;
  volume.value_offset = base;
  volume.voxels.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double v = static_cast<double>(load<T>(src + i * sizeof(T)));
    const double k = std::round((v - base) / step);
    // Out of int16's range as well: the tolerance grows with the values, and huge ones could
    // pass it with a level past the grid (found by fuzz_nrrd: undefined behaviour, not a load).
    if (!(k >= -32768.0 && k <= 32767.0) || std::abs(k * step + base - v) > tol) {
      volume.voxels.clear();
      return fail(ErrorCode::kUnsupported, what, why);
    }
    volume.voxels[i] = static_cast<std::int16_t>(k);
  }
  return Ok{};
}

Status convert(const std::vector<std::uint8_t>& raw, std::size_t n, const std::string& what,
               ScalarType type, Volume& volume) {
  const std::uint8_t* p = raw.data();
  switch (type) {
    case ScalarType::kInt8:
      return convertInteger<std::int8_t>(p, n, what, type, volume);
    case ScalarType::kUInt8:
      return convertInteger<std::uint8_t>(p, n, what, type, volume);
    case ScalarType::kInt16:
      return convertInteger<std::int16_t>(p, n, what, type, volume);
    case ScalarType::kUInt16:
      return convertInteger<std::uint16_t>(p, n, what, type, volume);
    case ScalarType::kInt32:
      return convertInteger<std::int32_t>(p, n, what, type, volume);
    case ScalarType::kUInt32:
      return convertInteger<std::uint32_t>(p, n, what, type, volume);
    case ScalarType::kFloat:
      return convertFloating<float>(p, n, what, type, volume);
    case ScalarType::kDouble:
      return convertFloating<double>(p, n, what, type, volume);
  }
  return fail(ErrorCode::kInternal, what, "unknown scalar type");
}

// ---- small text helpers ----

std::vector<std::string> words(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> out;
  for (std::string w; in >> w;)
    out.push_back(w);
  return out;
}

bool parseDouble(const std::string& s, double& out) {
  const std::string t = trim(s);
  if (t.empty()) return false;
  char* end = nullptr;
  out = std::strtod(t.c_str(), &end);
  return end == t.c_str() + t.size() && std::isfinite(out);
}

bool parseInt64(const std::string& s, std::int64_t& out) {
  const std::string t = trim(s);
  if (t.empty()) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtoll(t.c_str(), &end, 10);
  return errno == 0 && end == t.c_str() + t.size();
}

// "(a,b,c)" -> vector; false for "none" or anything malformed.
bool parseNrrdVector(const std::string& s, Eigen::Vector3d& v) {
  std::string t;
  for (char c : s) {
    if (!std::isspace(static_cast<unsigned char>(c))) t += c;
  }
  if (t.size() < 2 || t.front() != '(' || t.back() != ')') return false;
  std::istringstream in(t.substr(1, t.size() - 2));
  std::string part;
  int i = 0;
  while (std::getline(in, part, ',')) {
    if (i >= 3 || !parseDouble(part, v[i])) return false;
    ++i;
  }
  return i == 3;
}

// Splits "(..) (..) (..)" or "none (..)" into items, keeping each parenthesised group whole.
std::vector<std::string> vectorItems(const std::string& s) {
  std::vector<std::string> items;
  std::size_t i = 0;
  while (i < s.size()) {
    if (std::isspace(static_cast<unsigned char>(s[i]))) {
      ++i;
    } else if (s[i] == '(') {
      const auto close = s.find(')', i);
      const auto end = close == std::string::npos ? s.size() : close + 1;
      items.push_back(s.substr(i, end - i));
      i = end;
    } else {
      std::size_t j = i;
      while (j < s.size() && !std::isspace(static_cast<unsigned char>(s[j])))
        ++j;
      items.push_back(s.substr(i, j - i));
      i = j;
    }
  }
  return items;
}

bool nrrdType(const std::string& name, ScalarType& t) {
  static const struct {
    const char* names;
    ScalarType type;
  } kTypes[] = {
      {"|signed char|int8|int8_t|", ScalarType::kInt8},
      {"|uchar|unsigned char|uint8|uint8_t|", ScalarType::kUInt8},
      {"|short|short int|signed short|signed short int|int16|int16_t|", ScalarType::kInt16},
      {"|ushort|unsigned short|unsigned short int|uint16|uint16_t|", ScalarType::kUInt16},
      {"|int|signed int|int32|int32_t|", ScalarType::kInt32},
      {"|uint|unsigned int|uint32|uint32_t|", ScalarType::kUInt32},
      {"|float|", ScalarType::kFloat},
      {"|double|", ScalarType::kDouble},
  };
  const std::string key = "|" + lower(name) + "|";
  for (const auto& entry : kTypes) {
    if (std::string(entry.names).find(key) != std::string::npos) {
      t = entry.type;
      return true;
    }
  }
  return false;
}

std::string fmt(double v) {
  std::ostringstream o;
  o << std::setprecision(17) << v;
  return o.str();
}

}  // namespace

const char* detail::toString(ScalarType type) {
  switch (type) {
    case ScalarType::kInt8:
      return "int8";
    case ScalarType::kUInt8:
      return "uint8";
    case ScalarType::kInt16:
      return "int16";
    case ScalarType::kUInt16:
      return "uint16";
    case ScalarType::kInt32:
      return "int32";
    case ScalarType::kUInt32:
      return "uint32";
    case ScalarType::kFloat:
      return "float";
    case ScalarType::kDouble:
      return "double";
  }
  return "?";
}

Status detail::readRaster(const RasterSource& source, const std::string& what,
                          const ProgressCallback& progress, Volume& volume) {
  const std::size_t n = volume.geometry.voxelCount();
  if (n == 0 || n > kMaxVoxels) {
    return fail(ErrorCode::kInternal, what, "readRaster called with an unvalidated geometry");
  }
  const std::size_t width = sizeOf(source.type);
  const std::uint64_t bytes = static_cast<std::uint64_t>(n) * width;
  std::error_code ec;
  const std::uint64_t file_bytes = fs::file_size(source.data_path, ec);
  if (ec) {
    return fail(ErrorCode::kIo, what,
                "cannot read data file '" + source.data_path + "': " + ec.message());
  }
  std::uint64_t skip = 0;
  if (source.byte_skip == -1) {
    if (source.compressed) {
      return fail(ErrorCode::kFormat, what, "byte skip -1 is only allowed with raw data");
    }
    skip = file_bytes >= bytes ? file_bytes - bytes : file_bytes;  // short: caught below
  } else if (source.byte_skip < 0) {
    return fail(ErrorCode::kFormat, what,
                "byte skip " + std::to_string(source.byte_skip) + " is negative");
  } else {
    skip = static_cast<std::uint64_t>(source.byte_skip);
  }
  const std::uint64_t available = skip <= file_bytes ? file_bytes - skip : 0;
  const auto& d = volume.geometry.dims;
  const std::string declared = std::to_string(d[0]) + " x " + std::to_string(d[1]) + " x " +
                               std::to_string(d[2]) + " " + toString(source.type) + " = " +
                               std::to_string(bytes) + " bytes";
  // Check against the file before allocating anything the header asks for.
  if (!source.compressed && available < bytes) {
    return fail(ErrorCode::kFormat, what,
                "data shorter than declared: the header declares " + declared + " but '" +
                    source.data_path + "' holds only " + std::to_string(available) +
                    " bytes of data");
  }
  if (source.compressed && (available == 0 || bytes / kMaxInflateRatio > available)) {
    return fail(ErrorCode::kFormat, what,
                "data shorter than declared: the header declares " + declared + " but '" +
                    source.data_path + "' holds only " + std::to_string(available) +
                    " compressed bytes (zlib expands at most ~1032:1)");
  }
  std::ifstream in(source.data_path, std::ios::binary);
  if (!in) return fail(ErrorCode::kIo, what, "cannot open data file '" + source.data_path + "'");
  in.seekg(static_cast<std::streamoff>(skip));
  if (!in) return fail(ErrorCode::kFormat, what, "cannot seek to the data");

  try {
    report(progress, 0, static_cast<std::size_t>(bytes));
    // int16 decodes straight into the volume; other types go through one staging buffer.
    const bool direct = source.type == ScalarType::kInt16;
    std::vector<std::uint8_t> staging;
    std::uint8_t* dst = nullptr;
    if (direct) {
      volume.voxels.assign(n, 0);
      dst = reinterpret_cast<std::uint8_t*>(volume.voxels.data());
    } else {
      staging.resize(static_cast<std::size_t>(bytes));
      dst = staging.data();
    }
    Status s = source.compressed
                   ? inflateAll(in, dst, static_cast<std::size_t>(bytes), what, progress)
                   : readRaw(in, dst, static_cast<std::size_t>(bytes), what, progress);
    if (!s.ok()) {
      volume.voxels.clear();
      return s;
    }
    if (source.big_endian != hostIsBigEndian()) {
      swapBytes(dst, static_cast<std::size_t>(bytes), width);
    }
    if (direct) {
      volume.value_scale = 1.0;
      volume.value_offset = 0.0;
      return Ok{};
    }
    return convert(staging, n, what, source.type, volume);
  } catch (const std::bad_alloc&) {
    volume.voxels.clear();
    return fail(ErrorCode::kIo, what, "not enough memory for " + declared);
  }
}

namespace {

// readNrrd, and readNrrdLayers when `layers` is given: then a first axis that lists components
// (dimension 4, its space direction "none") is taken, and key:=value pairs are kept there.
Expected<Volume> readNrrdImage(const std::string& path, const ProgressCallback& progress,
                               NrrdLayers* layers) {
  const std::string& what = path;
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(ErrorCode::kIo, what, "cannot open the file");
  std::string line;
  if (!readLine(in, line, 64) || line.rfind("NRRD000", 0) != 0 || line.size() < 8 ||
      !std::isdigit(static_cast<unsigned char>(line[7]))) {
    return fail(ErrorCode::kFormat, what, "not a NRRD file (no 'NRRD000x' magic on line 1)");
  }

  // Fields, lower-cased names; key:=value pairs and comments are skipped.
  HeaderFields fields;
  bool blank_line = false;
  std::size_t header_bytes = line.size() + 1;
  while (readLine(in, line, kMaxHeaderBytes)) {
    header_bytes += line.size() + 1;
    if (header_bytes > kMaxHeaderBytes) {
      return fail(ErrorCode::kFormat, what, "header longer than 1 MiB without a blank line");
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) {
      blank_line = true;
      break;
    }
    if (line[0] == '#') continue;
    const auto colon = line.find(':');
    if (colon != std::string::npos && colon + 1 < line.size() && line[colon + 1] == '=') {
      if (layers) layers->key_values.emplace_back(line.substr(0, colon), line.substr(colon + 2));
      continue;
    }
    if (colon == std::string::npos || colon + 1 >= line.size() || line[colon + 1] != ' ') {
      return fail(ErrorCode::kFormat, what, "malformed header line '" + printable(line) + "'");
    }
    fields.add(lower(trim(line.substr(0, colon))), trim(line.substr(colon + 2)));
  }

  const std::string* dimension = fields.find({"dimension"});
  if (dimension == nullptr) return missingField(what, "dimension");
  std::int64_t dim = 0;
  if (!parseInt64(*dimension, dim)) {
    return fail(ErrorCode::kFormat, what, "dimension '" + *dimension + "' is not an integer");
  }
  if (dim != 3 && !(layers && dim == 4)) {
    return fail(ErrorCode::kUnsupported, what,
                "dimension " + std::to_string(dim) +
                    (layers ? " (3D volumes, or 3D with a first axis of layers, are supported)"
                            : " (only scalar 3D volumes are supported)"));
  }
  const std::size_t axes = static_cast<std::size_t>(dim);
  const std::size_t first_space_axis = axes - 3;  // 1: the first axis lists components
  const std::string* type_field = fields.find({"type"});
  if (type_field == nullptr) return missingField(what, "type");
  ScalarType type{};
  if (!nrrdType(*type_field, type)) {
    return fail(ErrorCode::kUnsupported, what, "voxel type '" + *type_field + "' is not supported");
  }
  const std::string* encoding_field = fields.find({"encoding"});
  if (encoding_field == nullptr) return missingField(what, "encoding");
  const std::string encoding = lower(*encoding_field);
  bool compressed = false;
  if (encoding == "gzip" || encoding == "gz") {
    compressed = true;
  } else if (encoding != "raw") {
    return fail(ErrorCode::kUnsupported, what,
                "encoding '" + *encoding_field + "' is not supported (raw and gzip are)");
  }
  bool big_endian = false;
  if (const std::string* endian = fields.find({"endian"})) {
    if (lower(*endian) == "big") {
      big_endian = true;
    } else if (lower(*endian) != "little") {
      return fail(ErrorCode::kFormat, what, "endian '" + *endian + "' is neither little nor big");
    }
  } else if (sizeOf(type) > 1) {
    return missingField(what, "endian");
  }

  Volume volume;
  Geometry& g = volume.geometry;
  const std::string* sizes = fields.find({"sizes"});
  if (sizes == nullptr) return missingField(what, "sizes");
  const auto size_words = words(*sizes);
  if (size_words.size() != axes) {
    return fail(ErrorCode::kFormat, what,
                "sizes '" + *sizes + "' must list " + std::to_string(axes) + " axes");
  }
  int components = 1;
  for (std::size_t a = 0; a < axes; ++a) {
    std::int64_t s = 0;
    if (!parseInt64(size_words[a], s) || s <= 0 || s > std::numeric_limits<int>::max()) {
      return fail(ErrorCode::kFormat, what, "sizes '" + *sizes + "' must be positive integers");
    }
    if (a < first_space_axis) {
      if (s > 255) {
        return fail(ErrorCode::kUnsupported, what,
                    "sizes '" + *sizes + "': more than 255 layers on the first axis");
      }
      components = static_cast<int>(s);
    } else {
      g.dims[a - first_space_axis] = static_cast<int>(s);
    }
  }
  if (const std::string* kinds = fields.find({"kinds"})) {
    const auto kind_words = words(*kinds);
    for (std::size_t a = 0; a < kind_words.size(); ++a) {
      const std::string k = lower(kind_words[a]);
      if (a < first_space_axis ? (k == "domain" || k == "space")
                               : (k != "domain" && k != "space")) {
        return fail(ErrorCode::kUnsupported, what,
                    "kinds '" + *kinds +
                        (layers ? "': the spatial axes must be domain axes (a first axis may list "
                                  "layers)"
                                : "': only scalar volumes (domain axes) are supported"));
      }
    }
  }

  // Geometry: space + space directions (columns = spacing * direction) + space origin.
  const std::string* space = fields.find({"space"});
  bool ras = false;
  if (space != nullptr) {
    const std::string s = lower(*space);
    if (s == "right-anterior-superior" || s == "ras") {
      ras = true;
    } else if (s != "left-posterior-superior" && s != "lps") {
      return fail(ErrorCode::kUnsupported, what,
                  "space '" + *space + "' (only left-posterior-superior and " +
                      "right-anterior-superior are supported)");
    }
  }
  if (const std::string* directions = fields.find({"space directions"})) {
    auto items = vectorItems(*directions);
    if (first_space_axis > 0 && !items.empty() && lower(items.front()) == "none") {
      items.erase(items.begin());
    }
    if (items.size() != 3) {
      return fail(ErrorCode::kFormat, what,
                  "space directions '" + *directions + "' must hold 3 vectors" +
                      (first_space_axis > 0 ? " after 'none' for the layers" : ""));
    }
    for (int a = 0; a < 3; ++a) {
      Eigen::Vector3d v;
      if (!parseNrrdVector(items[static_cast<std::size_t>(a)], v)) {
        return fail(ErrorCode::kFormat, what,
                    "space directions: axis " + std::to_string(a) + " '" +
                        items[static_cast<std::size_t>(a)] + "' is not a 3-vector");
      }
      const double norm = v.norm();
      if (!(norm > 0.0)) {
        return fail(
            ErrorCode::kFormat, what,
            "space directions: axis " + std::to_string(a) + " has zero length (zero spacing)");
      }
      g.spacing_mm[a] = norm;
      g.direction.col(a) = v / norm;
    }
  } else if (const std::string* spacings = fields.find({"spacings"})) {
    const auto w = words(*spacings);
    for (int a = 0; a < 3; ++a) {
      if (w.size() != 3 || !parseDouble(w[static_cast<std::size_t>(a)], g.spacing_mm[a])) {
        return fail(ErrorCode::kFormat, what, "spacings '" + *spacings + "' must hold 3 numbers");
      }
    }
  } else {
    return missingField(what, "space directions");
  }
  if (const std::string* origin = fields.find({"space origin"})) {
    if (!parseNrrdVector(*origin, g.origin_lps_mm)) {
      return fail(ErrorCode::kFormat, what, "space origin '" + *origin + "' is not a 3-vector");
    }
  }
  if (ras) {  // RAS -> LPS: negate x and y of every direction and of the origin
    g.direction.row(0) *= -1.0;
    g.direction.row(1) *= -1.0;
    g.origin_lps_mm.x() *= -1.0;
    g.origin_lps_mm.y() *= -1.0;
  }
  if (auto s = g.validate(what); !s.ok()) return s.error();

  detail::RasterSource source;
  source.type = type;
  source.big_endian = big_endian;
  source.compressed = compressed;
  std::int64_t line_skip = 0;
  if (const std::string* ls = fields.find({"line skip", "lineskip"})) {
    if (!parseInt64(*ls, line_skip) || line_skip < 0) {
      return fail(ErrorCode::kFormat, what, "line skip '" + *ls + "' is not a count");
    }
  }
  if (const std::string* bs = fields.find({"byte skip", "byteskip"})) {
    if (!parseInt64(*bs, source.byte_skip) || source.byte_skip < -1) {
      return fail(ErrorCode::kFormat, what, "byte skip '" + *bs + "' is invalid");
    }
  }
  if (compressed && (line_skip != 0 || source.byte_skip != 0)) {
    return fail(ErrorCode::kUnsupported, what, "line skip / byte skip with gzip encoding");
  }
  if (const std::string* data_file = fields.find({"data file", "datafile"})) {
    if (data_file->rfind("LIST", 0) == 0 || data_file->find('%') != std::string::npos) {
      return fail(ErrorCode::kUnsupported, what,
                  "data file '" + *data_file + "': only a single data file is supported");
    }
    fs::path p(*data_file);
    if (p.is_relative()) p = fs::path(path).parent_path() / p;
    source.data_path = p.string();
    if (line_skip > 0) {  // skip text lines at the start of the data file
      std::ifstream data(source.data_path, std::ios::binary);
      std::string skipped;
      std::int64_t offset = 0;
      for (std::int64_t i = 0; i < line_skip; ++i) {
        if (!std::getline(data, skipped)) {
          return fail(ErrorCode::kFormat, what, "data file has fewer lines than line skip");
        }
        offset += static_cast<std::int64_t>(skipped.size()) + 1;
      }
      if (source.byte_skip == -1) {
        return fail(ErrorCode::kUnsupported, what, "line skip together with byte skip -1");
      }
      source.byte_skip += offset;
    }
  } else {
    if (!blank_line) {
      return fail(ErrorCode::kFormat, what,
                  "no blank line ends the header and no 'data file' is named (truncated?)");
    }
    if (line_skip != 0 || source.byte_skip != 0) {
      return fail(ErrorCode::kUnsupported, what, "line skip / byte skip in an attached NRRD");
    }
    source.data_path = path;
    source.byte_skip = static_cast<std::int64_t>(in.tellg());
    if (source.byte_skip < 0) return fail(ErrorCode::kIo, what, "cannot locate the data");
  }
  in.close();
  // The layers are read as a first axis `components` times longer: the raster is one stream.
  if (components > 1 && g.voxelCount() > kMaxVoxels / static_cast<std::size_t>(components)) {
    return fail(ErrorCode::kUnsupported, what, "more voxels than any volume may hold");
  }
  const Geometry spatial = g;
  g.dims[0] *= components;
  if (auto s = detail::readRaster(source, what, progress, volume); !s.ok()) return s.error();
  g = spatial;
  if (layers) layers->components = components;
  volume.description = fs::path(path).filename().string();
  return volume;
}

}  // namespace

Expected<Volume> readNrrd(const std::string& path, const ProgressCallback& progress) {
  return readNrrdImage(path, progress, nullptr);
}

Expected<NrrdLayers> readNrrdLayers(const std::string& path) {
  NrrdLayers layers;
  auto volume = readNrrdImage(path, {}, &layers);
  if (!volume) return volume.error();
  if (volume->value_scale != 1.0 || volume->value_offset != std::round(volume->value_offset) ||
      std::abs(volume->value_offset) > 32767.0) {
    return fail(ErrorCode::kUnsupported, path,
                "voxel values are not integer labels (8- or 16-bit integers are)");
  }
  layers.geometry = volume->geometry;
  const auto offset = static_cast<int>(volume->value_offset);
  layers.values.resize(volume->voxels.size());
  for (std::size_t i = 0; i < volume->voxels.size(); ++i) {
    const int v = volume->voxels[i] + offset;
    if (v < -32768 || v > 32767) {
      return fail(ErrorCode::kUnsupported, path, "a label value lies outside 16 bits");
    }
    layers.values[i] = static_cast<std::int16_t>(v);
  }
  return layers;
}

namespace {

// Writes header + n values (bytes_per_value each, made by fill a chunk at a time) to a sibling
// temporary, gzip-compressed or raw, then renames it: a failed write never leaves half a file.
Status writeAttachedNrrd(
    const std::string& path, const std::string& header, std::size_t n, std::size_t bytes_per_value,
    bool gzip,
    const std::function<void(std::size_t first, std::size_t count, std::uint8_t* out)>& fill) {
  const std::string tmp = path + ".part";
  std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
  if (!out) return fail(ErrorCode::kIo, path, "cannot create '" + tmp + "'");
  out.write(header.data(), static_cast<std::streamsize>(header.size()));

  z_stream zs{};
  // 15 + 16: gzip wrapper, as Slicer writes.
  if (gzip && deflateInit2(&zs, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 15 + 16, 8,
                           Z_DEFAULT_STRATEGY) != Z_OK) {
    return fail(ErrorCode::kInternal, path, "zlib deflateInit2 failed");
  }
  std::vector<std::uint8_t> chunk;
  std::vector<std::uint8_t> zout(std::size_t{1} << 20);
  const std::size_t per_chunk = std::size_t{1} << 18;  // values per chunk
  bool ok = true;
  for (std::size_t first = 0; ok && first < n; first += per_chunk) {
    const std::size_t count = std::min(per_chunk, n - first);
    chunk.resize(count * bytes_per_value);
    fill(first, count, chunk.data());
    const bool last = first + count >= n;
    if (!gzip) {
      out.write(reinterpret_cast<const char*>(chunk.data()),
                static_cast<std::streamsize>(chunk.size()));
      continue;
    }
    zs.next_in = chunk.data();
    zs.avail_in = static_cast<uInt>(chunk.size());
    int rc = Z_OK;
    do {
      zs.next_out = zout.data();
      zs.avail_out = static_cast<uInt>(zout.size());
      rc = deflate(&zs, last ? Z_FINISH : Z_NO_FLUSH);
      if (rc == Z_STREAM_ERROR) ok = false;
      out.write(reinterpret_cast<const char*>(zout.data()),
                static_cast<std::streamsize>(zout.size() - zs.avail_out));
    } while (ok && (zs.avail_out == 0 || (last && rc != Z_STREAM_END)));
  }
  if (gzip) deflateEnd(&zs);
  out.close();
  std::error_code ec;
  if (!ok || !out) {
    fs::remove(tmp, ec);
    return fail(ErrorCode::kIo, path, "writing failed (disk full?)");
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return fail(ErrorCode::kIo, path, "cannot rename the temporary file: " + ec.message());
  }
  return Ok{};
}

std::string spaceLines(const Geometry& g) {
  std::string out = "space directions:";
  for (int a = 0; a < 3; ++a) {
    const Eigen::Vector3d c = g.direction.col(a) * g.spacing_mm[a];
    out += " (" + fmt(c.x()) + "," + fmt(c.y()) + "," + fmt(c.z()) + ")";
  }
  return out;
}

}  // namespace

Status writeNrrd(const Volume& volume, const std::string& path, NrrdEncoding encoding) {
  const Geometry& g = volume.geometry;
  if (auto s = g.validate(path); !s.ok()) {
    return makeError(ErrorCode::kInvalidArgument, s.error().message);
  }
  const std::size_t n = g.voxelCount();
  if (volume.voxels.size() != n) {
    return fail(ErrorCode::kInvalidArgument, path,
                "volume holds " + std::to_string(volume.voxels.size()) + " voxels but its " +
                    "geometry declares " + std::to_string(n));
  }
  if (!std::isfinite(volume.value_scale) || !std::isfinite(volume.value_offset)) {
    return fail(ErrorCode::kInvalidArgument, path, "value scale or offset is not finite");
  }
  // int16 when physical values are exactly int16 (scale 1, integral offset, in range);
  // otherwise double, which holds v * scale + offset exactly enough to read back losslessly.
  bool as_int16 =
      volume.value_scale == 1.0 && volume.value_offset == std::round(volume.value_offset);
  if (as_int16 && !volume.voxels.empty()) {
    const auto [lo, hi] = std::minmax_element(volume.voxels.begin(), volume.voxels.end());
    as_int16 = *lo + volume.value_offset >= -32768.0 && *hi + volume.value_offset <= 32767.0;
  }
  std::ostringstream h;
  h << "NRRD0004\n"
    << "# Complete NRRD file format specification at:\n"
    << "# http://teem.sourceforge.net/nrrd/format.html\n"
    << "type: " << (as_int16 ? "short" : "double") << "\n"
    << "dimension: 3\n"
    << "space: left-posterior-superior\n"
    << "sizes: " << g.dims[0] << " " << g.dims[1] << " " << g.dims[2] << "\n"
    << spaceLines(g) << "\nkinds: domain domain domain\n"
    << "endian: " << (hostIsBigEndian() ? "big" : "little") << "\n"
    << "encoding: " << (encoding == NrrdEncoding::kGzip ? "gzip" : "raw") << "\n"
    << "space origin: (" << fmt(g.origin_lps_mm.x()) << "," << fmt(g.origin_lps_mm.y()) << ","
    << fmt(g.origin_lps_mm.z()) << ")\n\n";

  return writeAttachedNrrd(
      path, h.str(), n, as_int16 ? 2 : 8, encoding == NrrdEncoding::kGzip,
      [&](std::size_t first, std::size_t count, std::uint8_t* out) {
        for (std::size_t i = 0; i < count; ++i) {
          const std::int16_t s = volume.voxels[first + i];
          if (as_int16) {
            const auto v = static_cast<std::int16_t>(s + static_cast<int>(volume.value_offset));
            std::memcpy(out + 2 * i, &v, 2);
          } else {
            const double v = s * volume.value_scale + volume.value_offset;
            std::memcpy(out + 8 * i, &v, 8);
          }
        }
      });
}

Status writeNrrdVoxels(const Geometry& g, VoxelType voxel_type, const char* voxels,
                       std::size_t bytes, const std::string& path) {
  if (auto s = g.validate(path); !s.ok()) {
    return makeError(ErrorCode::kInvalidArgument, s.error().message);
  }
  // The same order as the readers' own type list.
  static_assert(static_cast<int>(VoxelType::kUInt16) == static_cast<int>(ScalarType::kUInt16) &&
                static_cast<int>(VoxelType::kDouble) == static_cast<int>(ScalarType::kDouble));
  const auto type = static_cast<ScalarType>(static_cast<int>(voxel_type));
  const std::size_t width = sizeOf(type);
  const std::size_t n = g.voxelCount();
  if (voxels == nullptr || bytes != n * width) {
    return fail(ErrorCode::kInvalidArgument, path,
                std::to_string(bytes) + " bytes of voxels; " + std::to_string(n) + " voxels of " +
                    detail::toString(type) + " are " + std::to_string(n * width));
  }
  std::ostringstream h;
  h << "NRRD0004\n"
    << "# Complete NRRD file format specification at:\n"
    << "# http://teem.sourceforge.net/nrrd/format.html\n"
    << "type: " << detail::toString(type) << "\n"
    << "dimension: 3\n"
    << "space: left-posterior-superior\n"
    << "sizes: " << g.dims[0] << " " << g.dims[1] << " " << g.dims[2] << "\n"
    << spaceLines(g) << "\nkinds: domain domain domain\n"
    << "endian: " << (hostIsBigEndian() ? "big" : "little") << "\n"
    << "encoding: raw\n"
    << "space origin: (" << fmt(g.origin_lps_mm.x()) << "," << fmt(g.origin_lps_mm.y()) << ","
    << fmt(g.origin_lps_mm.z()) << ")\n\n";
  return writeAttachedNrrd(path, h.str(), n, width, false,
                           [&](std::size_t first, std::size_t count, std::uint8_t* out) {
                             std::memcpy(out, voxels + first * width, count * width);
                           });
}

Status writeNrrdLayers(const NrrdLayers& image, const std::string& path) {
  const Geometry& g = image.geometry;
  if (auto s = g.validate(path); !s.ok()) {
    return makeError(ErrorCode::kInvalidArgument, s.error().message);
  }
  if (image.components < 1 || image.components > 255) {
    return fail(ErrorCode::kInvalidArgument, path, "1 to 255 layers are written");
  }
  const std::size_t n = g.voxelCount() * static_cast<std::size_t>(image.components);
  if (image.values.size() != n) {
    return fail(ErrorCode::kInvalidArgument, path,
                "holds " + std::to_string(image.values.size()) + " values, its geometry and " +
                    "layers declare " + std::to_string(n));
  }
  for (const auto v : image.values) {
    if (v < 0 || v > 255) return fail(ErrorCode::kInvalidArgument, path, "a label exceeds 8 bits");
  }
  const bool layered = image.components > 1;
  std::ostringstream h;
  h << "NRRD0004\n"
    << "# Complete NRRD file format specification at:\n"
    << "# http://teem.sourceforge.net/nrrd/format.html\n"
    << "type: unsigned char\n"
    << "dimension: " << (layered ? 4 : 3) << "\n"
    << "space: left-posterior-superior\n"
    << "sizes: ";
  if (layered) h << image.components << " ";
  h << g.dims[0] << " " << g.dims[1] << " " << g.dims[2] << "\n";
  std::string directions = spaceLines(g);
  if (layered) directions.insert(std::string("space directions:").size(), " none");
  h << directions << "\nkinds: " << (layered ? "list " : "") << "domain domain domain\n"
    << "encoding: gzip\n"
    << "space origin: (" << fmt(g.origin_lps_mm.x()) << "," << fmt(g.origin_lps_mm.y()) << ","
    << fmt(g.origin_lps_mm.z()) << ")\n";
  for (const auto& [key, value] : image.key_values) {
    if (key.find_first_of(":\n") != std::string::npos || value.find('\n') != std::string::npos) {
      return fail(ErrorCode::kInvalidArgument, path, "header key '" + key + "' cannot be written");
    }
    h << key << ":=" << value << "\n";
  }
  h << "\n";
  return writeAttachedNrrd(path, h.str(), n, 1, true,
                           [&](std::size_t first, std::size_t count, std::uint8_t* out) {
                             for (std::size_t i = 0; i < count; ++i)
                               out[i] = static_cast<std::uint8_t>(image.values[first + i]);
                           });
}

Expected<Volume> readVolumeFile(const std::string& path, const ProgressCallback& progress) {
  const std::string ext = lower(fs::path(path).extension().string());
  if (ext == ".nrrd" || ext == ".nhdr") return readNrrd(path, progress);
  if (ext == ".mha" || ext == ".mhd") return readMetaImage(path, progress);
  return fail(ErrorCode::kUnsupported, path,
              "not a NRRD (.nrrd, .nhdr) or MetaImage (.mha, .mhd) file: use the DICOM reader");
}

}  // namespace ignav::volume
