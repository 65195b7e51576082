#include "ignav/igtl/framing.hpp"

#include <array>
#include <cmath>
#include <cstring>

#include <fmt/format.h>

namespace ignav::igtl {
namespace {

constexpr std::uint64_t kPolynomial = 0x42F0E1EBA9EA3693ULL;

// Slicing-by-8 tables: table[0][b] is the CRC of byte b alone, table[k][b] that of byte b
// followed by k zero bytes; eight bytes are then folded in at once (a 157 MB image's CRC in
// ~0.1 s instead of ~0.4 s byte by byte).
using CrcTables = std::array<std::array<std::uint64_t, 256>, 8>;
CrcTables crcTables() {
  CrcTables t{};
  for (std::uint64_t b = 0; b < 256; ++b) {
    std::uint64_t r = b << 56;
    for (int bit = 0; bit < 8; ++bit)
      r = (r & (1ULL << 63)) ? (r << 1) ^ kPolynomial : r << 1;
    t[0][b] = r;
  }
  for (std::size_t k = 1; k < 8; ++k) {
    for (std::size_t b = 0; b < 256; ++b)
      t[k][b] = (t[k - 1][b] << 8) ^ t[0][t[k - 1][b] >> 56];
  }
  return t;
}
const CrcTables kCrc = crcTables();

std::string fixedField(const std::string& text, std::size_t size) {
  std::string field = text.substr(0, size);
  field.resize(size, '\0');
  return field;
}

std::string nameIn(const char* p, std::size_t size) {
  return std::string(p, strnlen(p, size));
}

}  // namespace

std::uint64_t readBigEndian(const char* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i)
    v = (v << 8) | static_cast<unsigned char>(p[i]);
  return v;
}

void appendBigEndian(std::string& out, std::uint64_t v, int bytes) {
  for (int i = bytes - 1; i >= 0; --i)
    out += static_cast<char>((v >> (8 * i)) & 0xff);
}

std::uint64_t crc64(std::string_view bytes, std::uint64_t crc) {
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  std::size_t n = bytes.size();
  for (; n >= 8; n -= 8, p += 8) {
    std::uint64_t word;
    std::memcpy(&word, p, 8);
    const std::uint64_t x = crc ^ __builtin_bswap64(word);  // the eight bytes, first one highest
    crc = kCrc[7][x >> 56] ^ kCrc[6][(x >> 48) & 0xff] ^ kCrc[5][(x >> 40) & 0xff] ^
          kCrc[4][(x >> 32) & 0xff] ^ kCrc[3][(x >> 24) & 0xff] ^ kCrc[2][(x >> 16) & 0xff] ^
          kCrc[1][(x >> 8) & 0xff] ^ kCrc[0][x & 0xff];
  }
  for (; n > 0; --n, ++p)
    crc = kCrc[0][((crc >> 56) ^ *p) & 0xff] ^ (crc << 8);
  return crc;
}

namespace {

// a * b mod the polynomial, both of degree < 64 (bit i the coefficient of x^i, as in the CRC
// register: a zero byte fed in multiplies it by x^8).
std::uint64_t multiplyModulo(std::uint64_t a, std::uint64_t b) {
  std::uint64_t product = 0;
  for (int bit = 63; bit >= 0; --bit) {
    product = (product & (1ULL << 63)) ? (product << 1) ^ kPolynomial : product << 1;
    if (b & (1ULL << bit)) product ^= a;
  }
  return product;
}

}  // namespace

std::uint64_t crc64Combine(std::uint64_t crc_a, std::uint64_t crc_b, std::uint64_t length_b) {
  // crc(A || B) = crc(A) x^(8 |B|) + crc(B) (initial value 0, no final XOR: the CRC is linear).
  std::uint64_t power = 1ULL << 8;  // x^8
  std::uint64_t shift = 1;          // x^0
  for (std::uint64_t n = length_b; n > 0; n >>= 1) {
    if (n & 1) shift = multiplyModulo(shift, power);
    power = multiplyModulo(power, power);
  }
  return multiplyModulo(crc_a, shift) ^ crc_b;
}

Header readHeader(const char* p) {
  Header h;
  h.version = static_cast<std::uint16_t>(readBigEndian(p, 2));
  h.type = nameIn(p + 2, kMaxTypeName);
  h.device_name = nameIn(p + 14, kMaxDeviceName);
  h.timestamp = readBigEndian(p + 34, 8);
  h.body_size = readBigEndian(p + 42, 8);
  h.crc = readBigEndian(p + 50, 8);
  return h;
}

std::string writeHeader(const Header& h) {
  std::string out;
  out.reserve(kHeaderBytes);
  appendBigEndian(out, h.version, 2);
  out += fixedField(h.type, kMaxTypeName);
  out += fixedField(h.device_name, kMaxDeviceName);
  appendBigEndian(out, h.timestamp, 8);
  appendBigEndian(out, h.body_size, 8);
  appendBigEndian(out, h.crc, 8);
  return out;
}

std::uint64_t timestampOf(double s) {
  if (!(s > 0) || s >= 4294967296.0) return 0;
  double whole = std::floor(s);
  auto fraction = static_cast<std::uint64_t>(std::llround((s - whole) * 4294967296.0));
  if (fraction > 0xffffffffULL) {  // rounded up to the next second
    fraction = 0;
    whole += 1;
  }
  return (static_cast<std::uint64_t>(whole) << 32) | fraction;
}

double secondsOf(std::uint64_t t) {
  return static_cast<double>(t >> 32) + static_cast<double>(t & 0xffffffffULL) / 4294967296.0;
}

Expected<BodyParts> splitBody(std::string_view body) {
  const auto bad = [](const std::string& what) { return makeError(ErrorCode::kFormat, what); };
  if (body.size() < kExtendedHeaderBytes) {
    return bad(
        fmt::format("body of {} bytes: a version-2 body starts with a {}-byte extended "
                    "header",
                    body.size(), kExtendedHeaderBytes));
  }
  BodyParts parts;
  parts.extended_header_size = static_cast<std::uint16_t>(readBigEndian(body.data(), 2));
  const std::uint64_t metadata_header_size = readBigEndian(body.data() + 2, 2);
  const std::uint64_t metadata_size = readBigEndian(body.data() + 4, 4);
  parts.message_id = static_cast<std::uint32_t>(readBigEndian(body.data() + 8, 4));
  if (parts.extended_header_size < kExtendedHeaderBytes) {
    return bad(fmt::format("extended header size {}: at least {}", parts.extended_header_size,
                           kExtendedHeaderBytes));
  }
  // In 64 bits: no sum of these fields can wrap.
  const std::uint64_t framing = parts.extended_header_size + metadata_header_size + metadata_size;
  if (framing > body.size()) {
    return bad(
        fmt::format("extended header ({}), metadata header ({}) and metadata ({}) "
                    "exceed the body's {} bytes",
                    parts.extended_header_size, metadata_header_size, metadata_size, body.size()));
  }
  const std::size_t content_size = body.size() - framing;
  parts.content = body.substr(parts.extended_header_size, content_size);
  if (metadata_header_size == 0) {
    if (metadata_size != 0) {
      return bad(fmt::format("metadata of {} bytes without a metadata header", metadata_size));
    }
    return parts;
  }
  const char* header = body.data() + parts.extended_header_size + content_size;
  const std::size_t count = readBigEndian(header, metadata_header_size >= 2 ? 2 : 1);
  if (metadata_header_size < 2 || metadata_header_size != 2 + kMetaDataEntryBytes * count) {
    return bad(fmt::format("metadata header size {} is not 2 + {} x {} entries",
                           metadata_header_size, kMetaDataEntryBytes, count));
  }
  const char* data = header + metadata_header_size;
  std::uint64_t used = 0;
  parts.metadata.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const char* e = header + 2 + kMetaDataEntryBytes * i;
    const std::uint64_t key_size = readBigEndian(e, 2);
    const auto encoding = static_cast<std::uint16_t>(readBigEndian(e + 2, 2));
    const std::uint64_t value_size = readBigEndian(e + 4, 4);
    if (used + key_size + value_size > metadata_size) {
      return bad(fmt::format("metadata entry {} ({} + {} bytes) runs past the metadata's {} bytes",
                             i + 1, key_size, value_size, metadata_size));
    }
    MetaDataEntry entry;
    entry.key.assign(data + used, key_size);
    entry.encoding = encoding;
    entry.value.assign(data + used + key_size, value_size);
    used += key_size + value_size;
    parts.metadata.push_back(std::move(entry));
  }
  if (used != metadata_size) {
    return bad(fmt::format("metadata entries hold {} bytes; the extended header says {}", used,
                           metadata_size));
  }
  return parts;
}

Expected<std::string> extendedHeader(std::uint32_t message_id,
                                     const std::vector<MetaDataEntry>& metadata) {
  if (metadata.size() > kMaxMetaDataEntries) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("{} metadata entries; at most {}", metadata.size(), kMaxMetaDataEntries));
  }
  std::uint64_t metadata_size = 0;
  for (const auto& e : metadata) {
    if (e.key.size() > 0xffff || e.value.size() > 0xffffffffULL) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("metadata '{}': key or value too long for its size field",
                                   e.key.substr(0, 32)));
    }
    metadata_size += e.key.size() + e.value.size();
  }
  if (metadata_size > 0xffffffffULL) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("metadata of {} bytes; its size field holds 32 bits", metadata_size));
  }
  std::string out;
  appendBigEndian(out, kExtendedHeaderBytes, 2);
  appendBigEndian(out, 2 + kMetaDataEntryBytes * metadata.size(), 2);
  appendBigEndian(out, metadata_size, 4);
  appendBigEndian(out, message_id, 4);
  return out;
}

void appendMetaData(std::string& out, const std::vector<MetaDataEntry>& metadata) {
  appendBigEndian(out, metadata.size(), 2);
  for (const auto& e : metadata) {
    appendBigEndian(out, e.key.size(), 2);
    appendBigEndian(out, e.encoding, 2);
    appendBigEndian(out, e.value.size(), 4);
  }
  for (const auto& e : metadata) {
    out += e.key;
    out += e.value;
  }
}

Expected<std::string> joinBody(std::string_view content, std::uint32_t message_id,
                               const std::vector<MetaDataEntry>& metadata) {
  auto out = extendedHeader(message_id, metadata);
  if (!out) return out;
  out->append(content);
  appendMetaData(*out, metadata);
  return out;
}

}  // namespace ignav::igtl
