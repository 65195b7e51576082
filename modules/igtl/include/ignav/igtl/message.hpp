// OpenIGTLink messages as values, and their wire form in header version 1 (protocol 1 and 2) or 2
// (protocol 3: a message id and metadata; framing.hpp). libOpenIGTLink packs and reads the
// contents it knows (STRING, STATUS, TRANSFORM, POINT, the GET_ queries); COMMAND and RTS_COMMAND,
// which it does not (Debian's is protocol 2), are ours. No sockets here.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/igtl/framing.hpp"

namespace ignav::igtl {

// OpenIGTLink's STATUS codes (igtlStatusMessage.h) that the BRP protocol uses.
enum class StatusCode : std::uint16_t {
  kOk = 1,
  kPanic = 3,  // emergency
  kNotFound = 4,
  kBusy = 6,
  kConfigurationError = 10,
  kResourceError = 11,  // e.g. a disk full
  kUnknownInstruction = 12,
  kNotReady = 13,
  kManualMode = 14,
  kHardwareFailure = 18,
};

struct Status {
  std::uint16_t code = 1;
  std::int64_t subcode = 0;
  std::string error_name;     // at most 19 characters (kMaxErrorName)
  std::string status_string;  // free text
};

struct Point {
  std::string name;
  std::string group;
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();  // float32 on the wire
};

// COMMAND and RTS_COMMAND (protocol 3): an id the answer repeats, a name, and a text (XML as
// OpenIGTLinkIO writes it: <Command Name="..." .../>).
struct Command {
  std::uint32_t id = 0;
  std::string name;  // at most 127 characters (kMaxCommandName)
  std::uint16_t encoding = kUsAscii;
  std::string text;
};

// IMAGE's scalar types, numbered as OpenIGTLink numbers them.
enum class ScalarType : std::uint8_t {
  kInt8 = 2,
  kUint8 = 3,
  kInt16 = 4,
  kUint16 = 5,
  kInt32 = 6,
  kUint32 = 7,
  kFloat32 = 10,
  kFloat64 = 11,
};
std::size_t scalarBytes(ScalarType type);  // 0 for a number that is none of them

// IMAGE: a volume with its geometry (the whole volume: sub-volumes are neither sent nor taken).
struct Image {
  std::array<int, 3> size{0, 0, 0};  // voxels along i, j, k (each 1..65535)
  ScalarType scalar_type = ScalarType::kInt16;
  std::uint8_t components = 1;
  // Voxel index (i, j, k, 1) -> position in mm, in RAS (`ras`) or LPS. Its columns' lengths are
  // the spacing. (On the wire OpenIGTLink gives the volume's centre, (size - 1) / 2 from voxel 0.)
  Eigen::Matrix4d ijk_to_mm = Eigen::Matrix4d::Identity();
  bool ras = true;
  // The voxels, i fastest, little-endian, `data_bytes` of them: shared with their owner (a loaded
  // CT's buffer) and not copied until encoded.
  std::shared_ptr<const char> data;
  std::size_t data_bytes = 0;
  // int16 stored values and the physical values they stand for (value * scale + offset): when
  // not 1 and 0, the voxels go out as float32 physical values (converted when encoded).
  double value_scale = 1.0;
  double value_offset = 0.0;
  bool rescaled() const { return value_scale != 1.0 || value_offset != 0.0; }
};

// POLYDATA (protocol 3; VTK's vtkPolyData): points, cells as VTK writes them, and dataset
// attributes. Its sizes are checked both ways (cells against the points, attributes against the
// points or cells they belong to).
struct PolyAttribute {
  // 0x00..0x04: per point (scalars, vectors, normals, tensors, RGBA); 0x10..0x14: per cell.
  std::uint8_t type = 0x10;
  std::uint8_t components = 1;  // 3 for vectors and normals, 9 for tensors, 4 for RGBA
  std::string name;             // at most 255 characters
  std::vector<float> values;    // `components` per point or cell
  bool perCell() const { return (type & 0x10) != 0; }
};
struct PolyData {
  std::vector<float> points;  // x, y, z per point (mm)
  // VTK's cell arrays: for each cell, its number of points n, then n point indices.
  std::vector<std::uint32_t> vertices, lines, polygons, strips;
  std::vector<PolyAttribute> attributes;
};
// The cells in a VTK cell array; nothing if it is malformed (a count past its end, an index past
// `points`).
std::optional<std::size_t> cellCount(const std::vector<std::uint32_t>& cells, std::size_t points);
constexpr std::size_t kPolyDataHeaderBytes = 40;  // ten uint32
constexpr std::size_t kMaxPolyAttributeName = 255;

// TDATA's element: a tool's pose (a 6D instrument unless said otherwise).
struct TrackingElement {
  std::string name;                                      // up to 20 characters
  std::uint8_t kind = 2;                                 // 1 tracker, 2 6D instrument, 3 3D, 4 5D
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();  // float32 upper 3x4 on the wire
};

struct Message {
  std::string type;         // "STRING", "STATUS", "TRANSFORM", "POINT", "GET_STATUS", ...
  std::string device_name;  // at most 20 characters
  // The header version it came in or goes out in: 1, or 2 with a message id and metadata (which
  // version 1 has no room for: they are not sent then).
  std::uint16_t header_version = 1;
  std::uint32_t message_id = 0;
  std::vector<MetaDataEntry> metadata;
  double timestamp_s = 0;  // seconds since 1970 (the header's; 0: none)
  std::string text;        // STRING (US-ASCII)
  Status status;           // STATUS
  // TRANSFORM: a 4x4 homogeneous matrix; the wire holds its upper 3x4 as float32.
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
  std::vector<Point> points;              // POINT
  Command command;                        // COMMAND, RTS_COMMAND
  Image image;                            // IMAGE
  std::vector<TrackingElement> tracking;  // TDATA
  PolyData poly;                          // POLYDATA
  std::uint32_t stream_interval_ms = 0;   // STT_TDATA: the least time between two frames
};

Message stringMessage(std::string device, std::string text);
// A STATUS. Its status string and error name go out as US-ASCII (asciiText), the error name cut
// to its field's 19 characters.
Message statusMessage(std::string device, StatusCode code, std::string status_string = {},
                      std::string error_name = {});
// `text` in US-ASCII, which OpenIGTLink's STATUS strings are: θ -> "theta", ° -> " deg", ± ->
// "+/-", → -> "->" and the like; any other non-ASCII character -> '?'; control characters -> ' '.
std::string asciiText(const std::string& text);
Message transformMessage(std::string device, const Eigen::Matrix4d& matrix);
// A query or stream control: GET_STATUS, GET_TRANS (OpenIGTLink's GET_TRANSFORM: type names
// have at most 12 characters), GET_IMAGE, STT_TDATA (its stream_interval_ms), STP_TDATA, ...
Message queryMessage(std::string type, std::string device);
// IMAGE named `device`.
Message imageMessage(std::string device, Image image);
// POLYDATA named `device`.
Message polyDataMessage(std::string device, PolyData poly);
// TDATA of one tool named `device`, its pose `matrix`.
Message trackingMessage(std::string device, const Eigen::Matrix4d& matrix);
// COMMAND or RTS_COMMAND ("COMMAND" as device name, as OpenIGTLinkIO sends them).
Message commandMessage(std::string type, std::uint32_t id, std::string name, std::string text);
// The value of a metadata key, if the message has it.
const std::string* metaDataValue(const Message& message, const std::string& key);

// The message's wire bytes in its header_version, with its CRC. Errors (kInvalidArgument) name
// the field: a device name over 20 characters, a non-finite matrix, an unsupported type, a
// command name over 127 characters.
Expected<std::string> encode(const Message& message);

// A message's bytes in parts, so that a large part (an image's voxels) is written to the socket
// from where it lies instead of being copied into one buffer first.
struct WireSegment {
  std::shared_ptr<const char> data;
  std::size_t size = 0;
};
struct Wire {
  std::vector<WireSegment> segments;
  // An IMAGE's voxels' own CRC (from 0): kept by a sender that sends the same voxels again.
  std::optional<std::uint64_t> voxel_crc;
  std::size_t size() const;
  std::string joined() const;
};
// encode() in parts. `known_voxel_crc`: the CRC of these very voxels, computed before (it is then
// not computed again; the body's CRC combines it in).
Expected<Wire> encodeWire(const Message& message, const std::uint64_t* known_voxel_crc = nullptr);

// Reassembles messages from a byte stream, in header version 1 or 2 alike. A message that is not
// one of ours, too large, inconsistent in its sizes or failing its CRC becomes an error that names
// it; the stream stays usable after it (its body is skipped: every header says how long its body
// is), so one bad message never costs the connection; but a header of any other version (reason
// "header_version") means this is no OpenIGTLink stream we can follow.
class Decoder {
 public:
  // Bodies up to `max_body_bytes`; an IMAGE's up to `max_image_bytes` (a CT a scanner bridge
  // sends).
  explicit Decoder(std::size_t max_body_bytes = 64 * 1024, std::uint64_t max_image_bytes = 0)
      : max_body_bytes_(max_body_bytes), max_image_bytes_(max_image_bytes) {}
  void feed(const char* bytes, std::size_t count);
  // The next whole message, an error for the next bad one, or nothing until more bytes come.
  std::optional<Expected<Message>> next();
  std::size_t buffered() const { return buffer_.size() + large_got_; }

 private:
  std::uint64_t limitFor(std::string_view type) const;
  // A body larger than kLargeBodyBytes is read straight into memory of its own (huge pages: a
  // 150 MB scan costs ~75 page faults, not ~38 000), and its CRC is computed as its bytes arrive,
  // not all at once when it is whole: the thread reading it never stops for ~0.1 s between reads.
  void startLargeBody();
  void takeIntoLargeBody(const char*& bytes, std::size_t& count);
  std::size_t max_body_bytes_;
  std::uint64_t max_image_bytes_;
  std::string buffer_;      // (while a large body arrives: its header, then what follows the body)
  std::uint64_t skip_ = 0;  // bytes of a refused body still to discard
  std::shared_ptr<char> large_;
  std::uint64_t large_size_ = 0, large_got_ = 0;
  std::uint64_t crc_ = 0;  // of large_'s first large_got_ bytes
};
// Bodies larger than this are read into memory of their own, their CRC computed as they arrive.
constexpr std::uint64_t kLargeBodyBytes = std::uint64_t{1} << 20;

constexpr std::size_t kImageHeaderBytes = 72;
constexpr std::size_t kTrackingElementBytes = 70;  // name, type, reserved, 12 float32
// COMMAND's name field holds 128 bytes, NUL-terminated.
constexpr std::size_t kCommandHeaderBytes = 138;
constexpr std::size_t kMaxCommandName = 127;
// The STATUS error name field holds 20 bytes, but libOpenIGTLink (and so 3D Slicer) reads it back
// as a C string without a terminator of its own: a 20-character name would run into whatever
// follows. So at most 19.
constexpr std::size_t kMaxErrorName = 19;

}  // namespace ignav::igtl
