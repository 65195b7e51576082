// An OpenIGTLink protocol-3 peer for the tests, written from the protocol's description (the
// header page and the version-3 message structure, github.com/openigtlink/OpenIGTLink,
// Documents/Protocol), not from ignav's codec: its own byte assembly and parsing, and the CRC of
// libOpenIGTLink (igtl_util.h's crc64), so that what the server writes is checked byte by byte by
// code that shares nothing with it. A POSIX socket on loopback.
#pragma once

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <igtl_util.h>

namespace ignav::igtl3_test {

// Big-endian bytes of `v`, `n` of them.
inline std::string be(std::uint64_t v, int n) {
  std::string out(static_cast<std::size_t>(n), '\0');
  for (int i = n - 1; i >= 0; --i, v >>= 8)
    out[static_cast<std::size_t>(i)] = static_cast<char>(v & 0xff);
  return out;
}

inline std::uint64_t fromBe(const std::string& s, std::size_t at, int n) {
  std::uint64_t v = 0;
  for (int i = 0; i < n; ++i)
    v = (v << 8) | static_cast<unsigned char>(s.at(at + static_cast<std::size_t>(i)));
  return v;
}

inline std::string padded(const std::string& text, std::size_t size) {
  std::string out = text.substr(0, size);
  out.resize(size, '\0');
  return out;
}

// libOpenIGTLink's CRC-64 of `bytes`.
inline std::uint64_t referenceCrc(const std::string& bytes) {
  std::vector<unsigned char> copy(bytes.begin(), bytes.end());
  return crc64(copy.data(), copy.size(), 0ULL);
}

struct Meta {
  std::string key;
  std::uint16_t encoding = 3;
  std::string value;
};

// A version-2 body: extended header (12 bytes), content, metadata header, metadata.
inline std::string body2(const std::string& content, std::uint32_t message_id,
                         const std::vector<Meta>& meta) {
  std::string keys_values;
  std::string meta_header = be(meta.size(), 2);
  for (const auto& m : meta) {
    meta_header += be(m.key.size(), 2) + be(m.encoding, 2) + be(m.value.size(), 4);
    keys_values += m.key + m.value;
  }
  return be(12, 2) + be(meta_header.size(), 2) + be(keys_values.size(), 4) + be(message_id, 4) +
         content + meta_header + keys_values;
}

// A whole message: the 58-byte header and `body` (CRC computed by libOpenIGTLink's crc64).
inline std::string frame(std::uint16_t version, const std::string& type, const std::string& device,
                         std::uint64_t timestamp, const std::string& body) {
  return be(version, 2) + padded(type, 12) + padded(device, 20) + be(timestamp, 8) +
         be(body.size(), 8) + be(referenceCrc(body), 8) + body;
}

// Contents, from the message pages.
inline std::string stringContent(const std::string& text) {
  return be(3, 2) + be(text.size(), 2) + text;  // US-ASCII
}
inline std::string commandContent(std::uint32_t id, const std::string& name,
                                  const std::string& text) {
  return be(id, 4) + padded(name, 128) + be(3, 2) + be(text.size(), 4) + text;
}
inline std::string beFloat(float f) {
  std::uint32_t bits;
  std::memcpy(&bits, &f, 4);
  return be(bits, 4);
}
inline float floatAt(const std::string& bytes, std::size_t at) {
  const auto bits = static_cast<std::uint32_t>(fromBe(bytes, at, 4));
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}
// IMAGE: the 72-byte image header (its version 1; components; scalar type; endian 2, little;
// coordinates 1, RAS; the size; the three axes times their spacing, column by column; the centre
// of the volume; the sub-volume: offset 0, the whole size), then the voxels, little-endian.
inline std::string imageContent(int scalar_type, int components, const int size[3],
                                const double axes[3][3], const double centre[3],
                                const std::string& voxels) {
  std::string out = be(1, 2) + be(components, 1) + be(scalar_type, 1) + be(2, 1) + be(1, 1);
  for (int a = 0; a < 3; ++a)
    out += be(size[a], 2);
  for (int a = 0; a < 3; ++a)
    for (int r = 0; r < 3; ++r)
      out += beFloat(static_cast<float>(axes[a][r]));
  for (int r = 0; r < 3; ++r)
    out += beFloat(static_cast<float>(centre[r]));
  for (int a = 0; a < 3; ++a)
    out += be(0, 2);
  for (int a = 0; a < 3; ++a)
    out += be(size[a], 2);
  return out + voxels;
}
// TRANSFORM: the upper 3x4 of a matrix as float32, column by column (R11 R21 R31 R12 ... PZ).
inline std::string transformContent(const float m[3][4]) {
  std::string out;
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 3; ++r) {
      std::uint32_t bits;
      std::memcpy(&bits, &m[r][c], 4);
      out += be(bits, 4);
    }
  }
  return out;
}

// A message as read from the wire, every field as it was.
struct Frame {
  std::uint16_t version = 0;
  std::string type, device;
  std::uint64_t timestamp = 0, body_size = 0, crc = 0;
  std::string body;  // whole
  std::string raw;   // the message's bytes, header and body
  bool crc_ok = false;
  // Version 2:
  std::uint16_t extended_header_size = 0, meta_header_size = 0;
  std::uint32_t meta_size = 0, message_id = 0;
  std::string content;
  std::vector<Meta> meta;
  bool sizes_ok = true;  // the parts' sizes add up to the body

  const std::string* metaValue(const std::string& key) const {
    for (const auto& m : meta)
      if (m.key == key) return &m.value;
    return nullptr;
  }
  // STRING's text, STATUS's code and strings, COMMAND's fields, read from the content.
  std::string stringText() const { return content.substr(4, fromBe(content, 2, 2)); }
  int statusCode() const { return static_cast<int>(fromBe(content, 0, 2)); }
  std::string statusErrorName() const { return std::string(content.c_str() + 10); }
  std::string statusString() const { return std::string(content.c_str() + 30); }
  std::uint32_t commandId() const { return static_cast<std::uint32_t>(fromBe(content, 0, 4)); }
  std::string commandName() const { return std::string(content.c_str() + 4); }
  std::string commandText() const { return content.substr(138, fromBe(content, 134, 4)); }
};

inline std::string nameField(const std::string& s, std::size_t at, std::size_t size) {
  const std::string field = s.substr(at, size);
  return field.substr(0, field.find('\0'));
}

// The first message of `bytes`, if it is all there; `used` is its length.
inline std::optional<Frame> parseFrame(const std::string& bytes, std::size_t& used) {
  if (bytes.size() < 58) return std::nullopt;
  Frame f;
  f.version = static_cast<std::uint16_t>(fromBe(bytes, 0, 2));
  f.type = nameField(bytes, 2, 12);
  f.device = nameField(bytes, 14, 20);
  f.timestamp = fromBe(bytes, 34, 8);
  f.body_size = fromBe(bytes, 42, 8);
  f.crc = fromBe(bytes, 50, 8);
  if (bytes.size() - 58 < f.body_size) return std::nullopt;
  f.body = bytes.substr(58, f.body_size);
  used = 58 + f.body_size;
  f.raw = bytes.substr(0, used);
  f.crc_ok = referenceCrc(f.body) == f.crc;
  if (f.version != 2) {
    f.content = f.body;
    return f;
  }
  if (f.body.size() < 12) {
    f.sizes_ok = false;
    return f;
  }
  f.extended_header_size = static_cast<std::uint16_t>(fromBe(f.body, 0, 2));
  f.meta_header_size = static_cast<std::uint16_t>(fromBe(f.body, 2, 2));
  f.meta_size = static_cast<std::uint32_t>(fromBe(f.body, 4, 4));
  f.message_id = static_cast<std::uint32_t>(fromBe(f.body, 8, 4));
  const std::uint64_t framing =
      std::uint64_t{f.extended_header_size} + f.meta_header_size + f.meta_size;
  if (framing > f.body.size() || f.meta_header_size < 2) {
    f.sizes_ok = false;
    return f;
  }
  const std::size_t content_size = f.body.size() - framing;
  f.content = f.body.substr(f.extended_header_size, content_size);
  const std::size_t mh = f.extended_header_size + content_size;
  const std::size_t count = fromBe(f.body, mh, 2);
  f.sizes_ok = f.meta_header_size == 2 + 8 * count;
  std::size_t at = mh + f.meta_header_size, total = 0;
  for (std::size_t i = 0; i < count && f.sizes_ok; ++i) {
    Meta m;
    const std::size_t key_size = fromBe(f.body, mh + 2 + 8 * i, 2);
    m.encoding = static_cast<std::uint16_t>(fromBe(f.body, mh + 4 + 8 * i, 2));
    const std::size_t value_size = fromBe(f.body, mh + 6 + 8 * i, 4);
    m.key = f.body.substr(at, key_size);
    m.value = f.body.substr(at + key_size, value_size);
    at += key_size + value_size;
    total += key_size + value_size;
    f.meta.push_back(m);
  }
  f.sizes_ok = f.sizes_ok && total == f.meta_size && at == f.body.size();
  return f;
}

// The peer: connects to the server's OpenIGTLink port, sends bytes, reads frames.
class Peer {
 public:
  explicit Peer(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    const int on = 1;
    ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
  }
  ~Peer() { close(); }
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;
  bool connected() const { return connected_; }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

  void send(const std::string& bytes) {
    std::size_t sent = 0;
    while (sent < bytes.size()) {
      const ssize_t n = ::send(fd_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      ASSERT_GT(n, 0) << "send failed";
      sent += static_cast<std::size_t>(n);
    }
  }

  // The next frame within `timeout`; nothing when none came (or the server closed: closed()).
  std::optional<Frame> next(std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      std::size_t used = 0;
      if (auto f = parseFrame(buffer_, used)) {
        buffer_.erase(0, used);
        return f;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          until - std::chrono::steady_clock::now());
      if (left.count() <= 0 || closed_) return std::nullopt;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
      char chunk[65536];
      const ssize_t n = ::recv(fd_, chunk, sizeof chunk, 0);
      if (n <= 0) {
        closed_ = true;
        continue;
      }
      buffer_.append(chunk, static_cast<std::size_t>(n));
    }
  }

  // Frames until one satisfies `wanted` (returned), every frame seen kept in `seen`.
  std::optional<Frame> until(const std::function<bool(const Frame&)>& wanted,
                             std::vector<Frame>* seen = nullptr,
                             std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          end - std::chrono::steady_clock::now());
      if (left.count() <= 0) return std::nullopt;
      auto f = next(left);
      if (!f) return std::nullopt;
      if (seen) seen->push_back(*f);
      if (wanted(*f)) return f;
    }
  }
  bool closed() const { return closed_; }

 private:
  int fd_ = -1;
  bool connected_ = false;
  bool closed_ = false;
  std::string buffer_;
};

}  // namespace ignav::igtl3_test
