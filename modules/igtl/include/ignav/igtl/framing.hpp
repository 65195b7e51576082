// OpenIGTLink's framing, written from the protocol's description (the header page and the
// version-3 structure: github.com/openigtlink/OpenIGTLink, Documents/Protocol): the 58-byte header
// every message starts with, and for header version 2 (protocol version 3) the body's four parts:
// extended header, content, metadata header, metadata. Every number big-endian; the CRC is
// CRC-64 (ECMA-182) of the whole body. Pure: no sockets, no clock.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "ignav/core/expected.hpp"

namespace ignav::igtl {

constexpr std::size_t kHeaderBytes = 58;
constexpr std::size_t kMaxTypeName = 12;
constexpr std::size_t kMaxDeviceName = 20;
// Header version 2's extended header: its own size, the metadata header's, the metadata's, and
// the message id (2 + 2 + 4 + 4 bytes). A larger size announced by a peer is skipped over.
constexpr std::size_t kExtendedHeaderBytes = 12;
// A metadata header is a count and 8 bytes per entry (key size, value encoding, value size).
constexpr std::size_t kMetaDataEntryBytes = 8;
constexpr std::size_t kMaxMetaDataEntries = (0xffff - 2) / kMetaDataEntryBytes;  // a 16-bit size
constexpr std::uint16_t kUsAscii = 3;                                            // IANA MIBenum
constexpr std::uint16_t kUtf8 = 106;

// CRC-64 as OpenIGTLink computes it: ECMA-182's polynomial 0x42F0E1EBA9EA3693, MSB first, initial
// value 0, no final XOR. `crc` continues an earlier part.
std::uint64_t crc64(std::string_view bytes, std::uint64_t crc = 0);
// The CRC of A followed by B from the CRCs of each (B's computed from 0) and B's length, in
// O(log length): a large part's CRC is computed once and kept (an image sent again).
std::uint64_t crc64Combine(std::uint64_t crc_a, std::uint64_t crc_b, std::uint64_t length_b);

// Big-endian numbers of `bytes` bytes (1..8), as every OpenIGTLink number is.
std::uint64_t readBigEndian(const char* p, int bytes);
void appendBigEndian(std::string& out, std::uint64_t value, int bytes);

struct Header {
  std::uint16_t version = 1;
  std::string type;         // up to 12 characters
  std::string device_name;  // up to 20 characters
  std::uint64_t timestamp = 0;
  std::uint64_t body_size = 0;
  std::uint64_t crc = 0;
};

// The header's fields from its 58 bytes (names end at their first NUL).
Header readHeader(const char* bytes);
// Its 58 bytes. Longer names are cut to their fields (encode() refuses them before this).
std::string writeHeader(const Header& header);

// OpenIGTLink's timestamp: whole seconds since 1970 in the upper 32 bits, the fraction of a second
// in units of 2^-32 s in the lower. 0 means "unused".
std::uint64_t timestampOf(double seconds_since_epoch);
double secondsOf(std::uint64_t timestamp);

struct MetaDataEntry {
  std::string key;  // up to 65535 bytes
  std::uint16_t encoding = kUsAscii;
  std::string value;
  bool operator==(const MetaDataEntry& o) const {
    return key == o.key && encoding == o.encoding && value == o.value;
  }
};

// A version-2 body, taken apart. `content` points into the body given.
struct BodyParts {
  std::uint16_t extended_header_size = kExtendedHeaderBytes;
  std::uint32_t message_id = 0;
  std::string_view content;
  std::vector<MetaDataEntry> metadata;
};

// Splits a version-2 body. Every size is checked against the body before it is used; an error
// (kFormat) names the field that does not fit ("metadata header size 10 is not 2 + 8 x 3 entries").
Expected<BodyParts> splitBody(std::string_view body);
// The version-2 body around `content`. Errors (kInvalidArgument) name the entry too large for its
// field, or too many entries.
Expected<std::string> joinBody(std::string_view content, std::uint32_t message_id,
                               const std::vector<MetaDataEntry>& metadata);
// The same in parts, for a body assembled in place: the 12-byte extended header (checking what
// joinBody checks), and the metadata header and metadata appended after the content.
Expected<std::string> extendedHeader(std::uint32_t message_id,
                                     const std::vector<MetaDataEntry>& metadata);
void appendMetaData(std::string& out, const std::vector<MetaDataEntry>& metadata);

}  // namespace ignav::igtl
