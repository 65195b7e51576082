#include "ignav/igtl/message.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <utility>

#include <fmt/format.h>
#include <igtlMessageHeader.h>
#include <igtlPointMessage.h>
#include <igtlStatusMessage.h>
#include <igtlStringMessage.h>
#include <igtlTransformMessage.h>
#include <Eigen/LU>

#include "ignav/volume/volume.hpp"

namespace ignav::igtl {
namespace {

// Fixed sizes of the bodies we read (OpenIGTLink v2 specification).
constexpr std::size_t kTransformBody = 48;  // 12 float32
constexpr std::size_t kStatusFixed = 30;    // code, subcode, error name
constexpr std::size_t kStringFixed = 4;     // encoding, length
constexpr std::size_t kPointElement = 136;  // name, group, rgba, xyz, radius, owner

// What libOpenIGTLink packed, without its header: the content (our framing goes around it).
std::string contentOf(::igtl::MessageBase* m) {
  m->Pack();
  return std::string(static_cast<const char*>(m->GetPackBodyPointer()),
                     static_cast<std::size_t>(m->GetPackBodySize()));
}

Error bad(const std::string& what) {
  return makeError(ErrorCode::kInvalidArgument, what);
}

// Unpacks `content` into an `M` through libOpenIGTLink (our Decoder has checked the CRC of the
// whole body already).
template <class M>
Expected<typename M::Pointer> unpack(const Message& in, std::string_view content,
                                     const std::string& name) {
  Header h;
  h.type = in.type;
  h.device_name = in.device_name;
  h.body_size = content.size();
  const std::string header_bytes = writeHeader(h);
  auto header = ::igtl::MessageHeader::New();
  header->InitPack();
  std::memcpy(header->GetPackPointer(), header_bytes.data(), kHeaderBytes);
  header->Unpack();
  auto m = M::New();
  m->SetMessageHeader(header);
  m->AllocatePack();
  if (!content.empty()) std::memcpy(m->GetPackBodyPointer(), content.data(), content.size());
  if (!(m->Unpack(0) & ::igtl::MessageHeader::UNPACK_BODY)) {
    return makeError(ErrorCode::kFormat, name + ": malformed body");
  }
  return m;
}

// float32 on the wire: big-endian, as every OpenIGTLink number.
void appendFloat32(std::string& out, float f) {
  std::uint32_t bits;
  std::memcpy(&bits, &f, 4);
  appendBigEndian(out, bits, 4);
}

float readFloat32(const char* at) {
  const auto bits = static_cast<std::uint32_t>(readBigEndian(at, 4));
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

// POLYDATA's content: the ten counts and sizes, points, the four cell arrays, the attributes'
// headers (type byte, components byte, count: libOpenIGTLink's order), their NUL-terminated
// names padded to an even length, then their values.
// One of OpenIGTLink's attribute types (0x00..0x04 per point, 0x10..0x14 per cell).
bool knownAttributeType(const PolyAttribute& a) {
  return (a.type & ~0x10) <= 0x04 && a.components > 0;
}

Expected<std::string> polyDataBytes(const Message& in) {
  const PolyData& p = in.poly;
  const auto refuse = [&](const std::string& what) {
    return bad(fmt::format("POLYDATA '{}': {}", in.device_name, what));
  };
  if (p.points.size() % 3 != 0) return refuse("points must come as x, y, z");
  const std::size_t points = p.points.size() / 3;
  if (points > 0xffffffffULL) return refuse("more than 2^32 - 1 points");
  for (const float v : p.points) {
    if (!std::isfinite(v)) return refuse("a point has a non-finite coordinate");
  }
  const std::vector<std::uint32_t>* cells[] = {&p.vertices, &p.lines, &p.polygons, &p.strips};
  const char* cell_names[] = {"vertices", "lines", "polygons", "triangle strips"};
  std::size_t counts[4];
  for (int c = 0; c < 4; ++c) {
    auto n = cellCount(*cells[c], points);
    if (!n)
      return refuse(
          fmt::format("its {} are no VTK cell array over {} points", cell_names[c], points));
    counts[c] = *n;
  }
  for (const auto& a : p.attributes) {
    const int kind = a.type & 0x0f;
    if (!knownAttributeType(a)) {
      return refuse(fmt::format("attribute '{}': type 0x{:02x} with {} components", a.name, a.type,
                                a.components));
    }
    const int expected = kind == 1 || kind == 2 ? 3 : kind == 3 ? 9 : kind == 4 ? 4 : 0;
    if (expected != 0 && a.components != expected) {
      return refuse(fmt::format("attribute '{}': {} components; its type has {}", a.name,
                                a.components, expected));
    }
    if (a.name.size() > kMaxPolyAttributeName || a.name.find('\0') != std::string::npos) {
      return refuse(fmt::format("attribute name of {} characters; at most {}, no NUL",
                                a.name.size(), kMaxPolyAttributeName));
    }
    const std::size_t owners = a.perCell() ? counts[0] + counts[1] + counts[2] + counts[3] : points;
    if (a.values.size() != owners * a.components) {
      return refuse(fmt::format("attribute '{}' has {} values; {} {} x {} components need {}",
                                a.name, a.values.size(), owners, a.perCell() ? "cells" : "points",
                                a.components, owners * a.components));
    }
    for (const float v : a.values) {
      if (!std::isfinite(v))
        return refuse(fmt::format("attribute '{}' has a non-finite value", a.name));
    }
  }
  std::string out;
  std::size_t total = kPolyDataHeaderBytes + 4 * p.points.size();
  for (const auto* c : cells)
    total += 4 * c->size();
  for (const auto& a : p.attributes)
    total += 6 + a.name.size() + 1 + 4 * a.values.size();
  out.reserve(total + 1);
  appendBigEndian(out, points, 4);
  for (int c = 0; c < 4; ++c) {
    appendBigEndian(out, counts[c], 4);
    appendBigEndian(out, 4 * cells[c]->size(), 4);
  }
  appendBigEndian(out, p.attributes.size(), 4);
  for (const float v : p.points)
    appendFloat32(out, v);
  for (const auto* c : cells) {
    for (const std::uint32_t v : *c)
      appendBigEndian(out, v, 4);
  }
  std::size_t names = 0;
  for (const auto& a : p.attributes) {
    out += static_cast<char>(a.type);
    out += static_cast<char>(a.components);
    appendBigEndian(out, a.values.size() / a.components, 4);
    names += a.name.size() + 1;
  }
  for (const auto& a : p.attributes) {
    out += a.name;
    out += '\0';
  }
  if (names % 2 == 1) out += '\0';
  for (const auto& a : p.attributes) {
    for (const float v : a.values)
      appendFloat32(out, v);
  }
  return out;
}

// The content of `out` (type, device name and framing filled in) from its bytes.
// `owner` holds the bytes `body` views: an image's voxels are kept in it, not copied.
Expected<Message> decodeContent(Message out, std::string_view body,
                                const std::shared_ptr<const void>& owner = nullptr) {
  const std::string name = fmt::format("{} message '{}'", out.type, out.device_name);
  const auto format = [&](const std::string& what) {
    return makeError(ErrorCode::kFormat, name + ": " + what);
  };
  if (out.type == "STRING") {
    if (body.size() < kStringFixed) return format("body shorter than 4 bytes");
    const std::size_t length = readBigEndian(body.data() + 2, 2);
    if (length > body.size() - kStringFixed) {
      return format(fmt::format("string length {} exceeds its body ({} bytes)", length,
                                body.size() - kStringFixed));
    }
    out.text.assign(body.data() + kStringFixed, length);  // not NUL-terminated on the wire
  } else if (out.type == "STATUS") {
    if (body.size() < kStatusFixed + 1 || body.back() != '\0') {
      return format("body must hold code, subcode, error name and a NUL-terminated string");
    }
    auto m = unpack<::igtl::StatusMessage>(out, body, name);
    if (!m) return m.error();
    out.status.code = static_cast<std::uint16_t>((*m)->GetCode());
    out.status.subcode = (*m)->GetSubCode();
    out.status.error_name.assign(body.data() + 10, strnlen(body.data() + 10, 20));
    out.status.status_string = std::string(body.data() + kStatusFixed);
  } else if (out.type == "IMAGE") {
    if (body.size() < kImageHeaderBytes) {
      return format(fmt::format("body has {} bytes; an image header alone has {}", body.size(),
                                kImageHeaderBytes));
    }
    const char* h = body.data();
    Image& image = out.image;
    const auto version = readBigEndian(h, 2);
    image.components = static_cast<std::uint8_t>(h[2]);
    image.scalar_type = static_cast<ScalarType>(static_cast<unsigned char>(h[3]));
    const int endian = static_cast<unsigned char>(h[4]);
    const int coordinates = static_cast<unsigned char>(h[5]);
    const std::size_t bytes = scalarBytes(image.scalar_type);
    if (version != 1 && version != 2) {
      return format(fmt::format("image header version {}; 1 or 2", version));
    }
    if (bytes == 0) {
      return format(fmt::format("scalar type {} is none of OpenIGTLink's",
                                static_cast<int>(static_cast<unsigned char>(h[3]))));
    }
    if (image.components == 0) return format("an image of 0 components");
    if ((endian != 1 && endian != 2) || (coordinates != 1 && coordinates != 2)) {
      return format(fmt::format("endian {} / coordinates {}: 1 or 2 each", endian, coordinates));
    }
    image.ras = coordinates == 1;
    std::uint64_t voxels = 1;
    for (int a = 0; a < 3; ++a) {
      image.size[a] = static_cast<int>(readBigEndian(h + 6 + 2 * a, 2));
      const auto offset = readBigEndian(h + 60 + 2 * a, 2);
      const auto extent = readBigEndian(h + 66 + 2 * a, 2);
      if (image.size[a] == 0) return format("an image with no voxels along an axis");
      if (offset != 0 || extent != static_cast<std::uint64_t>(image.size[a])) {
        return format("a partial image (a sub-volume) is not taken: send the whole volume");
      }
      voxels *= static_cast<std::uint64_t>(image.size[a]);
    }
    const std::uint64_t expected = voxels * image.components * bytes;
    if (expected != body.size() - kImageHeaderBytes) {
      return format(fmt::format("{} bytes of voxels; {} x {} x {} voxels of {} x {} bytes are {}",
                                body.size() - kImageHeaderBytes, image.size[0], image.size[1],
                                image.size[2], image.components, bytes, expected));
    }
    float f[12];
    for (int i = 0; i < 12; ++i)
      f[i] = readFloat32(h + 12 + 4 * i);
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r)
        m(r, c) = f[3 * c + r];
    const Eigen::Vector3d centre(f[9], f[10], f[11]);
    if (!m.allFinite() || !centre.allFinite() ||
        std::abs(m.topLeftCorner<3, 3>().determinant()) < 1e-12) {
      return format("the image's axes are not finite, or do not span a volume");
    }
    const Eigen::Vector3d half((image.size[0] - 1) / 2.0, (image.size[1] - 1) / 2.0,
                               (image.size[2] - 1) / 2.0);
    m.topRightCorner<3, 1>() = centre - m.topLeftCorner<3, 3>() * half;
    image.ijk_to_mm = m;
    const std::string_view values = body.substr(kImageHeaderBytes);
    image.data_bytes = values.size();
    if (owner && (endian == 2 || bytes == 1)) {
      image.data = std::shared_ptr<const char>(owner, values.data());  // where they were read
    } else {
      auto data = std::make_shared<std::string>(values);
      if (endian == 1 && bytes > 1) {  // big-endian voxels: ours are little-endian
        for (std::size_t at = 0; at < data->size(); at += bytes)
          std::reverse(data->begin() + static_cast<std::ptrdiff_t>(at),
                       data->begin() + static_cast<std::ptrdiff_t>(at + bytes));
      }
      image.data = std::shared_ptr<const char>(data, data->data());
    }
  } else if (out.type == "TDATA") {
    if (body.size() % kTrackingElementBytes != 0) {
      return format(fmt::format("body has {} bytes; tracking data come in {}-byte elements",
                                body.size(), kTrackingElementBytes));
    }
    for (std::size_t at = 0; at < body.size(); at += kTrackingElementBytes) {
      TrackingElement e;
      e.name.assign(body.data() + at, strnlen(body.data() + at, kMaxDeviceName));
      e.kind = static_cast<std::uint8_t>(body[at + 20]);
      for (int i = 0; i < 12; ++i)
        e.matrix(i % 3, i / 3) = readFloat32(body.data() + at + 22 + 4 * i);
      if (!e.matrix.allFinite()) {
        return format(fmt::format("element '{}' has a non-finite matrix", e.name));
      }
      out.tracking.push_back(std::move(e));
    }
  } else if (out.type == "STT_TDATA") {
    // The least time between frames (the coordinate system's name after it is not used here).
    if (body.size() >= 4)
      out.stream_interval_ms = static_cast<std::uint32_t>(readBigEndian(body.data(), 4));
  } else if (out.type == "COMMAND" || out.type == "RTS_COMMAND") {
    if (body.size() < kCommandHeaderBytes) {
      return format(fmt::format("body has {} bytes; a command's fixed part alone has {}",
                                body.size(), kCommandHeaderBytes));
    }
    const std::uint64_t length = readBigEndian(body.data() + 134, 4);
    if (length > body.size() - kCommandHeaderBytes) {
      return format(fmt::format("command length {} exceeds its body ({} bytes)", length,
                                body.size() - kCommandHeaderBytes));
    }
    const std::size_t name_length = strnlen(body.data() + 4, kMaxCommandName + 1);
    if (name_length > kMaxCommandName) {
      return format(fmt::format("the command name is not NUL-terminated within its {} bytes",
                                kMaxCommandName + 1));
    }
    out.command.id = static_cast<std::uint32_t>(readBigEndian(body.data(), 4));
    out.command.name.assign(body.data() + 4, name_length);
    out.command.encoding = static_cast<std::uint16_t>(readBigEndian(body.data() + 132, 2));
    out.command.text.assign(body.data() + kCommandHeaderBytes, length);
  } else if (out.type == "TRANSFORM") {
    if (body.size() != kTransformBody) {
      return format(
          fmt::format("body has {} bytes; a transform has {}", body.size(), kTransformBody));
    }
    auto m = unpack<::igtl::TransformMessage>(out, body, name);
    if (!m) return m.error();
    ::igtl::Matrix4x4 matrix;
    (*m)->GetMatrix(matrix);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        out.matrix(r, c) = matrix[r][c];
    out.matrix.row(3) << 0, 0, 0, 1;
    if (!out.matrix.allFinite()) return format("the matrix has a non-finite element");
  } else if (out.type == "POINT") {
    if (body.empty() || body.size() % kPointElement != 0) {
      return format(fmt::format("body has {} bytes; points come in {}-byte elements", body.size(),
                                kPointElement));
    }
    auto m = unpack<::igtl::PointMessage>(out, body, name);
    if (!m) return m.error();
    for (int i = 0; i < (*m)->GetNumberOfPointElement(); ++i) {
      ::igtl::PointElement::Pointer e;
      (*m)->GetPointElement(i, e);
      float xyz[3];
      e->GetPosition(xyz);
      Point p;
      p.name = e->GetName();
      p.group = e->GetGroupName();
      p.position_mm = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
      if (!p.position_mm.allFinite()) {
        return format(fmt::format("point {} has a non-finite coordinate", i + 1));
      }
      out.points.push_back(p);
    }
  } else if (out.type == "POLYDATA") {
    if (body.size() < kPolyDataHeaderBytes) {
      return format(fmt::format("body has {} bytes; its counts alone have {}", body.size(),
                                kPolyDataHeaderBytes));
    }
    const char* h = body.data();
    const std::uint64_t points = readBigEndian(h, 4);
    std::uint64_t cell_counts[4], cell_bytes[4];
    for (int c = 0; c < 4; ++c) {
      cell_counts[c] = readBigEndian(h + 4 + 8 * c, 4);
      cell_bytes[c] = readBigEndian(h + 8 + 8 * c, 4);
    }
    const std::uint64_t attributes = readBigEndian(h + 36, 4);
    // Every size in 64 bits from 32-bit fields: no sum below can overflow.
    std::uint64_t at = kPolyDataHeaderBytes + 12 * points;
    for (int c = 0; c < 4; ++c) {
      if (cell_bytes[c] % 4 != 0) return format("a cell array's size is no multiple of 4");
      at += cell_bytes[c];
    }
    at += 6 * attributes;
    if (at > body.size()) {
      return format(
          fmt::format("{} points, their cells and {} attribute headers need {} bytes; "
                      "the body has {}",
                      points, attributes, at, body.size()));
    }
    PolyData& p = out.poly;
    std::size_t pos = kPolyDataHeaderBytes;
    p.points.resize(3 * points);
    for (auto& v : p.points) {
      v = readFloat32(h + pos);
      pos += 4;
      if (!std::isfinite(v)) return format("a point has a non-finite coordinate");
    }
    std::vector<std::uint32_t>* cells[] = {&p.vertices, &p.lines, &p.polygons, &p.strips};
    const char* cell_names[] = {"vertices", "lines", "polygons", "triangle strips"};
    std::uint64_t all_cells = 0;
    for (int c = 0; c < 4; ++c) {
      cells[c]->resize(cell_bytes[c] / 4);
      for (auto& v : *cells[c]) {
        v = static_cast<std::uint32_t>(readBigEndian(h + pos, 4));
        pos += 4;
      }
      const auto n = cellCount(*cells[c], points);
      if (!n || *n != cell_counts[c]) {
        return format(fmt::format("its {} are no cell array of {} cells over {} points",
                                  cell_names[c], cell_counts[c], points));
      }
      all_cells += cell_counts[c];
    }
    p.attributes.resize(attributes);
    std::uint64_t data_bytes = 0;
    for (auto& a : p.attributes) {
      a.type = static_cast<std::uint8_t>(h[pos]);
      a.components = static_cast<std::uint8_t>(h[pos + 1]);
      const std::uint64_t owners = readBigEndian(h + pos + 2, 4);
      pos += 6;
      if (!knownAttributeType(a) || owners != (a.perCell() ? all_cells : points)) {
        return format(
            fmt::format("an attribute of type 0x{:02x}, {} components, for {} of {} "
                        "points and {} cells",
                        a.type, a.components, owners, points, all_cells));
      }
      data_bytes += 4 * owners * a.components;
    }
    // Checked before anything is allocated for them (sizes a sender may have lied about).
    if (at + data_bytes > body.size()) {
      return format(fmt::format("its attributes' values need {} bytes; the body has {} left",
                                data_bytes, body.size() - at));
    }
    for (auto& a : p.attributes)
      a.values.resize((a.perCell() ? all_cells : points) * a.components);
    std::size_t names = 0;
    for (auto& a : p.attributes) {
      const std::size_t length =
          strnlen(h + pos, std::min<std::size_t>(body.size() - pos, kMaxPolyAttributeName + 1));
      if (length > kMaxPolyAttributeName || pos + length >= body.size()) {
        return format("an attribute name is not NUL-terminated within 256 bytes of its body");
      }
      a.name.assign(h + pos, length);
      pos += length + 1;
      names += length + 1;
    }
    if (names % 2 == 1) ++pos;
    if (pos + data_bytes != body.size()) {
      return format(fmt::format("{} bytes of attribute values; the body has {} after the names",
                                data_bytes, body.size() - std::min<std::size_t>(pos, body.size())));
    }
    for (auto& a : p.attributes) {
      for (auto& v : a.values) {
        v = readFloat32(h + pos);
        pos += 4;
        if (!std::isfinite(v))
          return format(fmt::format("attribute '{}' has a non-finite value", a.name));
      }
    }
  } else if (out.type.rfind("GET_", 0) == 0 || out.type.rfind("STT_", 0) == 0 ||
             out.type.rfind("STP_", 0) == 0) {
    // Queries and stream controls carry no body we read.
  } else {
    return makeError(ErrorCode::kUnsupported, name + ": message type not handled here");
  }
  return out;
}

}  // namespace

Message stringMessage(std::string device, std::string text) {
  Message m;
  m.type = "STRING";
  m.device_name = std::move(device);
  m.text = std::move(text);
  return m;
}

std::string asciiText(const std::string& text) {
  // The signs our messages use, in words a US-ASCII reader shows; anything else becomes '?'.
  static constexpr std::pair<const char*, const char*> kWords[] = {
      {"\u03b8", "theta"},  {"\u00b0", " deg"},  {"\u00b1", "+/-"}, {"\u00b5", "u"},
      {"\u03bb", "lambda"}, {"\u00d7", "x"},     {"\u2192", "->"},  {"\u2264", "<="},
      {"\u2265", ">="},     {"\u2212", "-"},     {"\u2026", "..."}, {"\u2013", "-"},
      {"\u2014", "-"},      {"\u00b2", "^2"},    {"\u00b3", "^3"},  {"\u2248", "~"},
      {"\u03c6", "phi"},    {"\u03b3", "gamma"}, {"\u2202", "d"}};
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      out += (c >= 0x20 || c == '\n' || c == '\t') ? static_cast<char>(c) : ' ';
      ++i;
      continue;
    }
    bool named = false;
    for (const auto& [utf8, word] : kWords) {
      const std::size_t n = std::char_traits<char>::length(utf8);
      if (text.compare(i, n, utf8) == 0) {
        out += word;
        i += n;
        named = true;
        break;
      }
    }
    if (named) continue;
    out += '?';
    ++i;  // past the lead byte and its continuation bytes
    while (i < text.size() && (static_cast<unsigned char>(text[i]) & 0xC0) == 0x80)
      ++i;
  }
  return out;
}

Message statusMessage(std::string device, StatusCode code, std::string status_string,
                      std::string error_name) {
  Message m;
  m.type = "STATUS";
  m.device_name = std::move(device);
  m.status.code = static_cast<std::uint16_t>(code);
  m.status.status_string = asciiText(status_string);
  m.status.error_name = asciiText(error_name).substr(0, kMaxErrorName);
  return m;
}

Message transformMessage(std::string device, const Eigen::Matrix4d& matrix) {
  Message m;
  m.type = "TRANSFORM";
  m.device_name = std::move(device);
  m.matrix = matrix;
  return m;
}

Message queryMessage(std::string type, std::string device) {
  Message m;
  m.type = std::move(type);
  m.device_name = std::move(device);
  return m;
}

Message commandMessage(std::string type, std::uint32_t id, std::string name, std::string text) {
  Message m;
  m.type = std::move(type);
  m.device_name = "COMMAND";
  m.header_version = 2;  // protocol 3's own messages
  m.command.id = id;
  m.command.name = std::move(name);
  m.command.text = std::move(text);
  return m;
}

std::size_t scalarBytes(ScalarType type) {
  switch (type) {
    case ScalarType::kInt8:
    case ScalarType::kUint8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUint16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUint32:
    case ScalarType::kFloat32:
      return 4;
    case ScalarType::kFloat64:
      return 8;
  }
  return 0;
}

Message trackingMessage(std::string device, const Eigen::Matrix4d& matrix) {
  Message m;
  m.type = "TDATA";
  m.tracking.push_back({device, 2, matrix});
  m.device_name = std::move(device);
  return m;
}

Message imageMessage(std::string device, Image image) {
  Message m;
  m.type = "IMAGE";
  m.device_name = std::move(device);
  m.image = std::move(image);
  return m;
}

Message polyDataMessage(std::string device, PolyData poly) {
  Message m;
  m.type = "POLYDATA";
  m.device_name = std::move(device);
  m.poly = std::move(poly);
  return m;
}

std::optional<std::size_t> cellCount(const std::vector<std::uint32_t>& cells, std::size_t points) {
  std::size_t count = 0;
  for (std::size_t at = 0; at < cells.size(); ++count) {
    const std::size_t n = cells[at];
    if (n > cells.size() - at - 1) return std::nullopt;
    for (std::size_t i = at + 1; i <= at + n; ++i) {
      if (cells[i] >= points) return std::nullopt;
    }
    at += n + 1;
  }
  return count;
}

const std::string* metaDataValue(const Message& m, const std::string& key) {
  for (const auto& e : m.metadata) {
    if (e.key == key) return &e.value;
  }
  return nullptr;
}

namespace {

// The content of a message libOpenIGTLink packs, or a COMMAND's (the version-1 body, the
// version-2 body's middle).
Expected<std::string> contentBytes(const Message& in) {
  if (in.type == "STRING") {
    if (in.text.size() > 0xffff) {
      return bad(
          fmt::format("STRING '{}': {} bytes; at most 65535", in.device_name, in.text.size()));
    }
    auto m = ::igtl::StringMessage::New();
    m->SetDeviceName(in.device_name.c_str());
    m->SetEncoding(kUsAscii);
    m->SetString(in.text.c_str());
    return contentOf(m);
  }
  if (in.type == "STATUS") {
    if (in.status.error_name.size() > kMaxErrorName) {
      return bad(fmt::format("STATUS '{}': error name '{}' over {} characters", in.device_name,
                             in.status.error_name, kMaxErrorName));
    }
    auto m = ::igtl::StatusMessage::New();
    m->SetDeviceName(in.device_name.c_str());
    m->SetCode(in.status.code);
    m->SetSubCode(in.status.subcode);
    m->SetErrorName(in.status.error_name.c_str());
    m->SetStatusString(in.status.status_string.c_str());
    return contentOf(m);
  }
  if (in.type == "TRANSFORM") {
    if (!in.matrix.allFinite()) {
      return bad(fmt::format("TRANSFORM '{}': non-finite matrix", in.device_name));
    }
    auto m = ::igtl::TransformMessage::New();
    m->SetDeviceName(in.device_name.c_str());
    ::igtl::Matrix4x4 matrix;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        matrix[r][c] = static_cast<float>(in.matrix(r, c));
    m->SetMatrix(matrix);
    return contentOf(m);
  }
  if (in.type == "POINT") {
    auto m = ::igtl::PointMessage::New();
    m->SetDeviceName(in.device_name.c_str());
    for (const auto& p : in.points) {
      if (!p.position_mm.allFinite()) {
        return bad(fmt::format("POINT '{}': non-finite position", in.device_name));
      }
      auto e = ::igtl::PointElement::New();
      e->SetName(p.name.c_str());
      e->SetGroupName(p.group.c_str());
      e->SetRGBA(255, 255, 0, 255);
      e->SetPosition(static_cast<float>(p.position_mm.x()), static_cast<float>(p.position_mm.y()),
                     static_cast<float>(p.position_mm.z()));
      e->SetRadius(1.0f);
      m->AddPointElement(e);
    }
    return contentOf(m);
  }
  if (in.type == "STT_TDATA") {  // the least interval, then a coordinate system's name (none)
    std::string out;
    appendBigEndian(out, in.stream_interval_ms, 4);
    out.append(32, '\0');
    return out;
  }
  // Queries (GET_STATUS, GET_TRANS for GET_TRANSFORM, GET_IMAGE, ...) and stream controls carry
  // no content.
  if (in.type.rfind("GET_", 0) == 0 || in.type.rfind("STT_", 0) == 0 ||
      in.type.rfind("STP_", 0) == 0) {
    return std::string();
  }
  if (in.type == "TDATA") {
    std::string out;
    for (const auto& e : in.tracking) {
      if (e.name.size() > kMaxDeviceName || !e.matrix.allFinite()) {
        return bad(
            fmt::format("TDATA '{}': element '{}': a name over 20 characters or a "
                        "non-finite matrix",
                        in.device_name, e.name.substr(0, 32)));
      }
      std::string name = e.name;
      name.resize(kMaxDeviceName, '\0');
      out += name;
      out += static_cast<char>(e.kind);
      out += '\0';
      for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 3; ++r)
          appendFloat32(out, static_cast<float>(e.matrix(r, c)));
      }
    }
    return out;
  }
  if (in.type == "POLYDATA") return polyDataBytes(in);
  if (in.type == "COMMAND" || in.type == "RTS_COMMAND") {
    if (in.command.name.size() > kMaxCommandName) {
      return bad(fmt::format("{} '{}': command name of {} characters; at most {}", in.type,
                             in.device_name, in.command.name.size(), kMaxCommandName));
    }
    if (in.command.text.size() > 0xffffffffULL) {
      return bad(fmt::format("{} '{}': command text too long", in.type, in.device_name));
    }
    std::string out;
    out.reserve(kCommandHeaderBytes + in.command.text.size());
    appendBigEndian(out, in.command.id, 4);
    std::string name = in.command.name;
    name.resize(kMaxCommandName + 1, '\0');
    out += name;
    appendBigEndian(out, in.command.encoding, 2);
    appendBigEndian(out, in.command.text.size(), 4);
    out += in.command.text;
    return out;
  }
  return bad("message type '" + in.type + "' is not one we send");
}

// An IMAGE's content: its 72-byte header (big-endian) and its voxels (little-endian, as ours).
ignav::Status appendImage(const Message& in, std::string& out, WireSegment& voxel_part) {
  const Image& image = in.image;
  const std::size_t bytes = scalarBytes(image.scalar_type);
  std::uint64_t voxels = 1;
  for (const int n : image.size) {
    if (n < 1 || n > 0xffff) {
      return bad(fmt::format("IMAGE '{}': size {} along an axis; 1..65535", in.device_name, n));
    }
    voxels *= static_cast<std::uint64_t>(n);
  }
  if (bytes == 0 || image.components == 0) {
    return bad(fmt::format("IMAGE '{}': no scalar type or no components", in.device_name));
  }
  if (voxels * image.components * bytes != image.data_bytes || !image.data) {
    return bad(fmt::format("IMAGE '{}': {} bytes of voxels for {} voxels of {} x {} bytes",
                           in.device_name, image.data_bytes, voxels, image.components, bytes));
  }
  const Eigen::Matrix4d& m = image.ijk_to_mm;
  if (!m.allFinite()) return bad(fmt::format("IMAGE '{}': non-finite geometry", in.device_name));
  const bool rescaled = image.rescaled();
  if (rescaled && image.scalar_type != ScalarType::kInt16) {
    return bad(fmt::format("IMAGE '{}': only int16 voxels are rescaled", in.device_name));
  }
  appendBigEndian(out, 1, 2);  // the image header's version
  out += static_cast<char>(image.components);
  out += static_cast<char>(rescaled ? ScalarType::kFloat32 : image.scalar_type);
  out += static_cast<char>(2);  // little-endian voxels
  out += static_cast<char>(image.ras ? 1 : 2);
  for (const int n : image.size)
    appendBigEndian(out, static_cast<std::uint64_t>(n), 2);
  // The axes (direction x spacing), then the centre of the volume.
  const Eigen::Vector3d half((image.size[0] - 1) / 2.0, (image.size[1] - 1) / 2.0,
                             (image.size[2] - 1) / 2.0);
  const Eigen::Vector3d centre = m.topLeftCorner<3, 3>() * half + m.topRightCorner<3, 1>();
  const auto appendFloat = [&](double v) { appendFloat32(out, static_cast<float>(v)); };
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      appendFloat(m(r, c));
  for (int r = 0; r < 3; ++r)
    appendFloat(centre[r]);
  for (int i = 0; i < 3; ++i)
    appendBigEndian(out, 0, 2);  // the sub-volume is the whole volume
  for (const int n : image.size)
    appendBigEndian(out, static_cast<std::uint64_t>(n), 2);
  if (!rescaled) {
    voxel_part = {image.data, image.data_bytes};  // sent from where they lie
    return Ok{};
  }
  const std::size_t count = image.data_bytes / 2;
  auto converted = std::make_shared<std::vector<float>>(count);
  for (std::size_t n = 0; n < count; ++n) {
    std::int16_t stored;
    std::memcpy(&stored, image.data.get() + 2 * n, 2);
    (*converted)[n] = static_cast<float>(stored * image.value_scale + image.value_offset);
  }
  voxel_part = {
      std::shared_ptr<const char>(converted, reinterpret_cast<const char*>(converted->data())),
      4 * count};
  return Ok{};
}

// The content of a message of ours (the version-1 body, the version-2 body's middle), appended.
ignav::Status appendContent(const Message& in, std::string& out, WireSegment& voxels) {
  if (in.type == "IMAGE") return appendImage(in, out, voxels);
  auto content = contentBytes(in);
  if (!content) return content.error();
  out += *content;
  return Ok{};
}

}  // namespace

std::size_t Wire::size() const {
  std::size_t n = 0;
  for (const auto& s : segments)
    n += s.size;
  return n;
}

std::string Wire::joined() const {
  std::string out;
  out.reserve(size());
  for (const auto& s : segments)
    out.append(s.data.get(), s.size);
  return out;
}

Expected<Wire> encodeWire(const Message& in, const std::uint64_t* known_voxel_crc) {
  if (in.device_name.size() > kMaxDeviceName) {
    return bad(fmt::format("device name '{}' has {} characters; OpenIGTLink allows {}",
                           in.device_name, in.device_name.size(), kMaxDeviceName));
  }
  if (in.type.size() > kMaxTypeName) {
    return bad(fmt::format("type '{}' has {} characters; OpenIGTLink allows {}", in.type,
                           in.type.size(), kMaxTypeName));
  }
  if (in.header_version != 1 && in.header_version != 2) {
    return bad(fmt::format("{} '{}': header version {}; 1 or 2", in.type, in.device_name,
                           in.header_version));
  }
  // Three parts: the header and everything before an image's voxels, the voxels (sent from
  // where they lie, never copied), and the metadata after them. The CRC runs over the body's
  // parts in turn (the voxels' own CRC combined in when it is known already).
  auto head = std::make_shared<std::string>(kHeaderBytes, '\0');
  if (in.header_version == 2) {
    auto extended = extendedHeader(in.message_id, in.metadata);
    if (!extended) {
      return bad(fmt::format("{} '{}': {}", in.type, in.device_name, extended.error().message));
    }
    *head += *extended;
  }
  WireSegment voxels;
  if (auto appended = appendContent(in, *head, voxels); !appended) return appended.error();
  auto tail = std::make_shared<std::string>();
  if (in.header_version == 2) appendMetaData(*tail, in.metadata);
  Wire wire;
  std::uint64_t crc = crc64(std::string_view(*head).substr(kHeaderBytes));
  if (voxels.size > 0) {
    const bool known = known_voxel_crc != nullptr && !in.image.rescaled();
    wire.voxel_crc =
        known ? *known_voxel_crc : crc64(std::string_view(voxels.data.get(), voxels.size));
    crc = crc64Combine(crc, *wire.voxel_crc, voxels.size);
  }
  crc = crc64(*tail, crc);
  Header h;
  h.version = in.header_version;
  h.type = in.type;
  h.device_name = in.device_name;
  h.timestamp = timestampOf(in.timestamp_s);
  h.body_size = head->size() - kHeaderBytes + voxels.size + tail->size();
  h.crc = crc;
  const std::string header = writeHeader(h);
  std::copy(header.begin(), header.end(), head->begin());
  wire.segments.push_back({std::shared_ptr<const char>(head, head->data()), head->size()});
  if (voxels.size > 0) wire.segments.push_back(std::move(voxels));
  if (!tail->empty()) {
    wire.segments.push_back({std::shared_ptr<const char>(tail, tail->data()), tail->size()});
  }
  return wire;
}

Expected<std::string> encode(const Message& in) {
  auto wire = encodeWire(in);
  if (!wire) return wire.error();
  return wire->joined();
}

std::uint64_t Decoder::limitFor(std::string_view type) const {
  return type == "IMAGE" ? std::max<std::uint64_t>(max_body_bytes_, max_image_bytes_)
                         : max_body_bytes_;
}

void Decoder::feed(const char* bytes, std::size_t count) {
  if (skip_ > 0) {
    const auto dropped = static_cast<std::size_t>(std::min<std::uint64_t>(skip_, count));
    skip_ -= dropped;
    bytes += dropped;
    count -= dropped;
  }
  if (large_) {
    takeIntoLargeBody(bytes, count);
    buffer_.append(bytes, count);  // what follows the body
    return;
  }
  buffer_.append(bytes, count);
  startLargeBody();
}

void Decoder::startLargeBody() {
  if (large_ || skip_ > 0 || buffer_.size() < kHeaderBytes) return;
  const Header h = readHeader(buffer_.data());
  if ((h.version != 1 && h.version != 2) || h.body_size <= kLargeBodyBytes ||
      h.body_size > limitFor(h.type)) {
    return;  // an ordinary body, or one next() refuses
  }
  const auto size = static_cast<std::size_t>(h.body_size);
  large_ = std::shared_ptr<char>(static_cast<char*>(volume::allocateVoxelMemory(size)),
                                 [size](char* p) { volume::freeVoxelMemory(p, size); });
  large_size_ = h.body_size;
  large_got_ = 0;
  crc_ = 0;
  // What came with the header moves over; the buffer keeps the header and what follows the body.
  const char* rest = buffer_.data() + kHeaderBytes;
  std::size_t count = buffer_.size() - kHeaderBytes;
  takeIntoLargeBody(rest, count);
  buffer_.erase(kHeaderBytes, buffer_.size() - kHeaderBytes - count);
}

void Decoder::takeIntoLargeBody(const char*& bytes, std::size_t& count) {
  const auto take =
      static_cast<std::size_t>(std::min<std::uint64_t>(count, large_size_ - large_got_));
  if (take == 0) return;
  std::memcpy(large_.get() + large_got_, bytes, take);
  crc_ = crc64(std::string_view(large_.get() + large_got_, take), crc_);
  large_got_ += take;
  bytes += take;
  count -= take;
}

std::optional<Expected<Message>> Decoder::next() {
  if (buffer_.size() < kHeaderBytes) return std::nullopt;
  const Header header = readHeader(buffer_.data());
  const std::uint64_t body = header.body_size;
  const std::string name = fmt::format("{} message '{}'", header.type, header.device_name);
  const auto refuse = [&](Error e) -> std::optional<Expected<Message>> {
    // Drop the header and as much of the body as is here; the rest is skipped as it arrives.
    const std::uint64_t here = std::min<std::uint64_t>(body, buffer_.size() - kHeaderBytes);
    buffer_.erase(0, kHeaderBytes + here);
    skip_ = body - here;
    startLargeBody();  // the next message's, if it is one and here
    return Expected<Message>(std::move(e));
  };
  if (header.version != 1 && header.version != 2) {
    // Not a stream we can follow (another protocol, most likely: its "body size" means nothing).
    return refuse(makeError(ErrorCode::kUnsupported,
                            fmt::format("{}: header version {}: OpenIGTLink has 1 (protocols 1 "
                                        "and 2) and 2 (protocol 3)",
                                        name, header.version),
                            "header_version"));
  }
  const std::uint64_t limit = limitFor(header.type);
  if (body > limit) {
    return refuse(
        makeError(ErrorCode::kInvalidArgument,
                  fmt::format("{}: body of {} bytes; at most {} accepted", name, body, limit)));
  }
  // The body, kept whole (an image's voxels stay where they were read): a large one in its own
  // memory, its CRC computed already; an ordinary one copied out of the buffer.
  std::shared_ptr<const void> owner;
  std::string_view body_bytes;
  std::uint64_t crc = 0;
  if (large_) {
    if (large_got_ < large_size_) return std::nullopt;
    body_bytes = std::string_view(large_.get(), large_size_);
    owner = std::move(large_);
    large_.reset();
    large_got_ = large_size_ = 0;
    crc = crc_;
    buffer_.erase(0, kHeaderBytes);
  } else {
    if (buffer_.size() - kHeaderBytes < body) return std::nullopt;
    auto copy = std::make_shared<std::string>(buffer_, kHeaderBytes, body);
    buffer_.erase(0, kHeaderBytes + body);
    body_bytes = *copy;
    owner = std::move(copy);
    crc = crc64(body_bytes);
  }
  startLargeBody();  // the next message's, if it is one and here
  if (crc != header.crc) {
    return Expected<Message>(makeError(ErrorCode::kFormat, name + ": CRC mismatch"));
  }
  Message out;
  out.type = header.type;
  out.device_name = header.device_name;
  out.header_version = header.version;
  out.timestamp_s = header.timestamp == 0 ? 0.0 : secondsOf(header.timestamp);
  if (header.version == 1) {
    return Expected<Message>(decodeContent(std::move(out), body_bytes, owner));
  }
  auto parts = splitBody(body_bytes);
  if (!parts) {
    return Expected<Message>(makeError(ErrorCode::kFormat, name + ": " + parts.error().message));
  }
  out.message_id = parts->message_id;
  out.metadata = std::move(parts->metadata);
  return Expected<Message>(decodeContent(std::move(out), parts->content, owner));
}

}  // namespace ignav::igtl
