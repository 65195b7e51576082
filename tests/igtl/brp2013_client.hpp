// A strict, in-order navigation client for the June 2013 ProstateBRP workphase protocol (as the
// ProstateBRP CommunicationTest suite's navigation client reads it; docs/OPENIGTLINK.md), written
// with libOpenIGTLink (its socket and its message classes). It reads one message at a time and
// checks each against the one expected next: nothing may be skipped, nothing may come in between.
//
// Every message is checked as it is read, whatever was expected: the body's CRC, and for a STATUS
// an error name that fits the 20-byte field with its terminator (at most 19 characters, read from
// the raw bytes: libOpenIGTLink reads a 20-character name past the field) and a status string of
// US-ASCII bytes only.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <functional>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlStatusMessage.h>
#include <igtlStringMessage.h>
#include <igtlTransformMessage.h>
#include <Eigen/Core>

#include "igtl_matrix.hpp"

namespace ignav::brp2013_test {

using Clock = std::chrono::steady_clock;
using Ms = std::chrono::milliseconds;

// One message as it came.
struct Message {
  std::string type;
  std::string device;
  bool crc_ok = false;
  double at_s = 0.0;  // since the connection was made
  // STRING
  int encoding = -1;
  std::string text;
  // STATUS
  int code = -1;
  std::string error_name;             // the field's bytes up to its first NUL
  bool error_name_terminated = true;  // a NUL within the field's 20 bytes
  std::string status_string;          // the bytes after the 30-byte header, up to the first NUL
  bool status_ascii = true;           // every byte of it below 0x80
  // TRANSFORM (the wire carries the upper 3x4 as float32; the last row is 0 0 0 1)
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
};

inline std::string describe(const Message& m) {
  std::ostringstream o;
  o << m.type << "(" << m.device;
  if (m.type == "STRING") o << ", \"" << m.text << "\", encoding " << m.encoding;
  if (m.type == "STATUS") {
    o << ", code " << m.code << ", name \"" << m.error_name << "\"";
    if (!m.error_name_terminated) o << " (unterminated)";
    o << ", \"";
    for (const char c : m.status_string) {
      const auto b = static_cast<unsigned char>(c);
      if (b < 0x20 || b >= 0x7f) {
        o << "\\x" << std::hex << std::setw(2) << std::setfill('0') << static_cast<int>(b)
          << std::dec;
      } else {
        o << c;
      }
    }
    o << "\"";
  }
  if (m.type == "TRANSFORM") {
    o << ", t = (" << m.matrix(0, 3) << ", " << m.matrix(1, 3) << ", " << m.matrix(2, 3) << ")";
  }
  if (!m.crc_ok) o << ", bad CRC";
  return o.str() + ")";
}

// What a matrix becomes on the wire: float32 elements, the upper 3x4 only.
inline Eigen::Matrix<double, 3, 4> onTheWire(const Eigen::Matrix4d& m) {
  return m.topRows<3>().cast<float>().cast<double>();
}

class StrictClient {
 public:
  explicit StrictClient(int port) : socket_(igtl::ClientSocket::New()), start_(Clock::now()) {
    connected_ = socket_->ConnectToServer("127.0.0.1", port) == 0;
    socket_->SetReceiveTimeout(20);  // the poll period of a read; each read has its own deadline
  }
  ~StrictClient() {
    socket_->CloseSocket();
    if (::testing::Test::HasFailure()) std::cerr << "OpenIGTLink transcript:\n" << transcript();
  }
  StrictClient(const StrictClient&) = delete;
  StrictClient& operator=(const StrictClient&) = delete;

  bool connected() const { return connected_; }
  bool closedByServer() const { return closed_; }
  std::string transcript() const {
    std::string out;
    for (const auto& line : transcript_)
      out += "  " + line + "\n";
    return out;
  }

  void sendString(const std::string& device, const std::string& text) {
    auto m = igtl::StringMessage::New();
    m->SetDeviceName(device.c_str());
    m->SetString(text.c_str());
    m->SetEncoding(3);  // US-ASCII
    m->Pack();
    log("> STRING(" + device + ", \"" + text + "\")");
    socket_->Send(m->GetPackPointer(), m->GetPackSize());
  }
  void sendTransform(const std::string& device, const Eigen::Matrix4d& matrix) {
    auto m = igtl::TransformMessage::New();
    m->SetDeviceName(device.c_str());
    igtl_test::setMatrix(*m, matrix);
    m->Pack();
    std::ostringstream t;
    t << "> TRANSFORM(" << device << ", t = (" << matrix(0, 3) << ", " << matrix(1, 3) << ", "
      << matrix(2, 3) << "))";
    log(t.str());
    socket_->Send(m->GetPackPointer(), m->GetPackSize());
  }

  // The next message, whatever it is, if its header has come within `timeout`; none on a timeout
  // or a closed connection. The checks every message must pass are made here.
  std::optional<Message> next(Ms timeout) {
    const auto until = Clock::now() + timeout;
    auto header = igtl::MessageHeader::New();
    header->InitPack();
    if (!receiveExactly(header->GetPackPointer(), header->GetPackSize(), until)) {
      return std::nullopt;
    }
    header->Unpack();
    Message m;
    m.type = header->GetDeviceType();
    m.device = header->GetDeviceName();
    m.at_s = std::chrono::duration<double>(Clock::now() - start_).count();
    const auto body_size = header->GetBodySizeToRead();
    if (body_size < 0 || body_size > (1 << 20)) {
      ADD_FAILURE() << m.type << "(" << m.device << ") announces a body of " << body_size
                    << " bytes";
      return std::nullopt;
    }
    const auto body_until = Clock::now() + std::chrono::seconds(2);
    auto read_body = [&](auto msg) {
      msg->SetMessageHeader(header);
      msg->AllocatePack();
      if (!receiveExactly(msg->GetPackBodyPointer(), static_cast<int>(msg->GetPackBodySize()),
                          body_until)) {
        ADD_FAILURE() << "the body of " << m.type << "(" << m.device << ") did not come";
        return false;
      }
      return true;
    };
    if (m.type == "STRING") {
      auto s = igtl::StringMessage::New();
      if (!read_body(s)) return std::nullopt;
      m.crc_ok = (s->Unpack(1) & igtl::MessageHeader::UNPACK_BODY) != 0;
      m.encoding = s->GetEncoding();
      m.text = s->GetString();
    } else if (m.type == "STATUS") {
      auto s = igtl::StatusMessage::New();
      if (!read_body(s)) return std::nullopt;
      // The raw body first: code (2), sub-code (8), error name (20), then the status string.
      const auto* raw = static_cast<const unsigned char*>(s->GetPackBodyPointer());
      const std::size_t n = s->GetPackBodySize();
      if (n >= 30) {
        const char* name = reinterpret_cast<const char*>(raw + 10);
        const std::size_t name_length = strnlen(name, 20);
        m.error_name.assign(name, name_length);
        m.error_name_terminated = name_length < 20;
        for (std::size_t i = 30; i < n && raw[i] != 0; ++i) {
          m.status_string.push_back(static_cast<char>(raw[i]));
          if (raw[i] >= 0x80) m.status_ascii = false;
        }
      } else {
        ADD_FAILURE() << "STATUS(" << m.device << ") has a body of " << n << " bytes (< 30)";
      }
      m.crc_ok = (s->Unpack(1) & igtl::MessageHeader::UNPACK_BODY) != 0;
      m.code = s->GetCode();
    } else if (m.type == "TRANSFORM") {
      auto t = igtl::TransformMessage::New();
      if (!read_body(t)) return std::nullopt;
      m.crc_ok = (t->Unpack(1) & igtl::MessageHeader::UNPACK_BODY) != 0;
      m.matrix = igtl_test::matrixOf(*t);
    } else {
      std::string skip(static_cast<std::size_t>(body_size), '\0');
      if (!skip.empty() &&
          !receiveExactly(skip.data(), static_cast<int>(skip.size()), body_until)) {
        return std::nullopt;
      }
      m.crc_ok = true;  // not ours to judge: the type alone is unexpected
    }
    log("< " + describe(m));
    // What every message anywhere must satisfy.
    EXPECT_TRUE(m.crc_ok) << describe(m);
    if (m.type == "STATUS") {
      EXPECT_TRUE(m.error_name_terminated && m.error_name.size() <= 19)
          << "the error name must fit the field with its NUL (at most 19 characters): "
          << describe(m);
      EXPECT_TRUE(m.status_ascii) << "the status string must be US-ASCII: " << describe(m);
    }
    return m;
  }

  // ---- checks: each reads exactly one message ----------------------------------------------

  void receive(Ms timeout, const std::string& expected, Message* out) {
    auto m = next(timeout);
    ASSERT_TRUE(m.has_value()) << (closed_ ? "the server closed the connection" : "nothing came")
                               << " within " << timeout.count() << " ms; expected " << expected;
    *out = *m;
  }

  void expectString(const std::string& device, const std::string& text, Ms timeout) {
    const std::string expected = "STRING(" + device + ", \"" + text + "\")";
    Message m;
    ASSERT_NO_FATAL_FAILURE(receive(timeout, expected, &m));
    ASSERT_EQ(m.type, "STRING") << "expected " << expected << ", got " << describe(m);
    ASSERT_EQ(m.device, device) << "expected " << expected << ", got " << describe(m);
    EXPECT_EQ(m.encoding, 3) << describe(m);
    ASSERT_EQ(m.text, text) << "expected " << expected << ", got " << describe(m);
  }

  void expectStatus(const std::string& device, int code, Ms timeout, Message* out = nullptr) {
    const std::string expected = "STATUS(" + device + ", code " + std::to_string(code) + ")";
    Message m;
    ASSERT_NO_FATAL_FAILURE(receive(timeout, expected, &m));
    ASSERT_EQ(m.type, "STATUS") << "expected " << expected << ", got " << describe(m);
    ASSERT_EQ(m.device, device) << "expected " << expected << ", got " << describe(m);
    ASSERT_EQ(m.code, code) << "expected " << expected << ", got " << describe(m);
    if (out) *out = m;
  }

  // STATUS(CURRENT_STATUS): code 1, the workphase in the error name, exactly.
  void expectCurrentStatus(const std::string& phase, Ms timeout) {
    Message m;
    ASSERT_NO_FATAL_FAILURE(expectStatus("CURRENT_STATUS", 1, timeout, &m));
    ASSERT_EQ(m.error_name, phase)
        << "CURRENT_STATUS names the workphase in its error name: " << describe(m);
  }

  void expectTransform(const std::string& device, Ms timeout, Message* out = nullptr) {
    const std::string expected = "TRANSFORM(" + device + ")";
    Message m;
    ASSERT_NO_FATAL_FAILURE(receive(timeout, expected, &m));
    ASSERT_EQ(m.type, "TRANSFORM") << "expected " << expected << ", got " << describe(m);
    ASSERT_EQ(m.device, device) << "expected " << expected << ", got " << describe(m);
    if (out) *out = m;
  }

  // TRANSFORM(ACK_<id>): the matrix sent, float32 element for element.
  void expectEcho(const std::string& id, const Eigen::Matrix4d& sent, Ms timeout) {
    Message m;
    ASSERT_NO_FATAL_FAILURE(expectTransform("ACK_" + id, timeout, &m));
    const Eigen::Matrix<double, 3, 4> got = m.matrix.topRows<3>();
    EXPECT_EQ(got, onTheWire(sent)) << "the echo differs from what was sent:\n"
                                    << got << "\nsent:\n"
                                    << onTheWire(sent);
  }

  // Nothing at all for `duration`.
  void expectNothing(Ms duration, const std::string& when) {
    if (auto m = next(duration)) {
      ADD_FAILURE() << "nothing may come " << when << "; got " << describe(*m);
    }
  }

  // Reads for `duration`; every message that comes must be `allowed`.
  void drain(Ms duration, const std::function<bool(const Message&)>& allowed,
             const std::string& what) {
    const auto until = Clock::now() + duration;
    for (auto now = Clock::now(); now < until; now = Clock::now()) {
      auto m = next(std::chrono::duration_cast<Ms>(until - now));
      if (!m) return;
      EXPECT_TRUE(allowed(*m)) << "only " << what << " may come now; got " << describe(*m);
    }
  }

 private:
  void log(const std::string& line) {
    std::ostringstream o;
    o << std::fixed << std::setprecision(3) << std::setw(8)
      << std::chrono::duration<double>(Clock::now() - start_).count() << " s  " << line;
    transcript_.push_back(o.str());
  }

  // `until` bounds the wait for the first byte; a message under way gets 2 s more to come whole
  // (a read given up half-way would lose the stream's framing).
  bool receiveExactly(void* data, int size, Clock::time_point until) {
    char* p = static_cast<char*>(data);
    int got = 0;
    while (got < size) {
      if (closed_) return false;
      if (Clock::now() > until) {
        if (got == 0) return false;
        ADD_FAILURE() << "a message stopped half-way (" << got << " of " << size << " bytes)";
        return false;
      }
      const int n = socket_->Receive(p + got, size - got, 0);
      if (n == 0) {
        closed_ = true;
        log("< (closed by the server)");
        return false;
      }
      if (n > 0) {
        if (got == 0) until = std::max(until, Clock::now() + std::chrono::seconds(2));
        got += n;
      }
    }
    return true;
  }

  igtl::ClientSocket::Pointer socket_;
  Clock::time_point start_;
  bool connected_ = false;
  bool closed_ = false;
  std::vector<std::string> transcript_;
};

}  // namespace ignav::brp2013_test
