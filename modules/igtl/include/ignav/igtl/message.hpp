// OpenIGTLink messages as values, and their wire form (libOpenIGTLink does the packing and the
// CRC). Only what the BRP workphase protocol uses: STRING, STATUS, TRANSFORM, POINT and the
// GET_STATUS / GET_TRANSFORM queries. No sockets here.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"

namespace ignav::igtl {

// OpenIGTLink's STATUS codes (igtlStatusMessage.h) that the BRP protocol uses.
enum class StatusCode : std::uint16_t {
  kOk = 1,
  kPanic = 3,  // emergency
  kNotFound = 4,
  kConfigurationError = 10,
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

struct Message {
  std::string type;         // "STRING", "STATUS", "TRANSFORM", "POINT", "GET_STATUS", ...
  std::string device_name;  // at most 20 characters
  std::string text;         // STRING (US-ASCII)
  Status status;            // STATUS
  // TRANSFORM: a 4x4 homogeneous matrix; the wire holds its upper 3x4 as float32.
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
  std::vector<Point> points;  // POINT
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
// GET_STATUS, GET_TRANS (OpenIGTLink's GET_TRANSFORM: type names have at most 12 characters).
Message queryMessage(std::string type, std::string device);

// The message's wire bytes (header version 1, CRC). Errors (kInvalidArgument) name the field:
// a device name over 20 characters, a non-finite matrix, an unsupported type.
Expected<std::string> encode(const Message& message);

// Reassembles messages from a byte stream. A message that is not one of ours, too large, or
// fails its CRC becomes an error that names it; the stream stays usable after it (its body is
// skipped), so one bad message never costs the connection; but a header of another version
// (reason "header_version") means the stream cannot be followed.
class Decoder {
 public:
  explicit Decoder(std::size_t max_body_bytes = 64 * 1024) : max_body_bytes_(max_body_bytes) {}
  void feed(const char* bytes, std::size_t count);
  // The next whole message, an error for the next bad one, or nothing until more bytes come.
  std::optional<Expected<Message>> next();
  std::size_t buffered() const { return buffer_.size(); }

 private:
  std::size_t max_body_bytes_;
  std::string buffer_;
  std::size_t skip_ = 0;  // bytes of a refused body still to discard
};

// Header size of every OpenIGTLink message (version 1 and 2).
constexpr std::size_t kHeaderBytes = 58;
constexpr std::size_t kMaxDeviceName = 20;
// The STATUS error name field holds 20 bytes, but libOpenIGTLink (and so 3D Slicer) reads it back
// as a C string without a terminator of its own: a 20-character name would run into whatever
// follows. So at most 19.
constexpr std::size_t kMaxErrorName = 19;

}  // namespace ignav::igtl
