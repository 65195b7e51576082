// A navigation-side OpenIGTLink client for the BRP tests, written with libOpenIGTLink itself
// (its socket and its message classes), so the server's wire format is checked by an
// implementation that is not ours.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <deque>
#include <optional>
#include <set>
#include <string>

#include <igtlClientSocket.h>
#include <igtlMessageHeader.h>
#include <igtlPointMessage.h>
#include <igtlStatusMessage.h>
#include <igtlStringMessage.h>
#include <igtlTransformMessage.h>
#include <Eigen/Core>

#include "igtl_matrix.hpp"

namespace ignav::brp_test {

struct Received {
  std::string type;
  std::string device;
  std::string text;  // STRING
  int code = 0;      // STATUS
  std::string error_name;
  std::string status_string;
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();  // TRANSFORM
};

inline std::ostream& operator<<(std::ostream& o, const Received& r) {
  o << r.type << "(" << r.device;
  if (r.type == "STRING") o << ", \"" << r.text << "\"";
  if (r.type == "STATUS") o << ", code " << r.code << ", \"" << r.status_string << "\"";
  return o << ")";
}

class BrpClient {
 public:
  explicit BrpClient(int port) : socket_(igtl::ClientSocket::New()) {
    connected_ = socket_->ConnectToServer("127.0.0.1", port) == 0;
    socket_->SetReceiveTimeout(100);
  }
  ~BrpClient() { socket_->CloseSocket(); }
  bool connected() const { return connected_; }
  void close() { socket_->CloseSocket(); }
  int fd() const { return socket_->GetConnected() ? 1 : 0; }

  void sendString(const std::string& device, const std::string& text) {
    auto m = igtl::StringMessage::New();
    m->SetDeviceName(device.c_str());
    m->SetString(text.c_str());
    m->Pack();
    socket_->Send(m->GetPackPointer(), m->GetPackSize());
  }
  void sendTransform(const std::string& device, const Eigen::Matrix4d& matrix) {
    auto m = igtl::TransformMessage::New();
    m->SetDeviceName(device.c_str());
    igtl_test::setMatrix(*m, matrix);
    m->Pack();
    socket_->Send(m->GetPackPointer(), m->GetPackSize());
  }
  void sendPoint(const std::string& device, const Eigen::Vector3d& ras_mm) {
    auto m = igtl::PointMessage::New();
    m->SetDeviceName(device.c_str());
    auto e = igtl::PointElement::New();
    e->SetName("target");
    e->SetGroupName("TARGET");
    e->SetPosition(static_cast<float>(ras_mm.x()), static_cast<float>(ras_mm.y()),
                   static_cast<float>(ras_mm.z()));
    m->AddPointElement(e);
    m->Pack();
    socket_->Send(m->GetPackPointer(), m->GetPackSize());
  }
  void sendGetStatus(const std::string& device) {
    auto m = igtl::GetStatusMessage::New();
    m->SetDeviceName(device.c_str());
    m->Pack();
    socket_->Send(m->GetPackPointer(), m->GetPackSize());
  }
  void sendGetTransform(const std::string& device) {
    auto m = igtl::GetTransformMessage::New();
    m->SetDeviceName(device.c_str());
    m->Pack();
    socket_->Send(m->GetPackPointer(), m->GetPackSize());
  }
  void sendRaw(const void* bytes, int n) { socket_->Send(bytes, n); }

  // The next message not in `ignore`, within `timeout`; nothing on timeout or a closed socket.
  std::optional<Received> next(std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < until) {
      auto r = receiveOne(until);
      if (!r) return std::nullopt;
      if (ignore_.count(r->device)) {
        streamed_.push_back(*r);
        continue;
      }
      return r;
    }
    return std::nullopt;
  }
  // Messages set aside (the live streams) since the last call.
  std::deque<Received> takeStreamed() {
    std::deque<Received> out;
    out.swap(streamed_);
    return out;
  }
  void ignore(const std::set<std::string>& devices) { ignore_ = devices; }
  bool closedByServer() const { return closed_; }

 private:
  bool receiveExactly(void* data, int size, std::chrono::steady_clock::time_point until) {
    char* p = static_cast<char*>(data);
    int got = 0;
    while (got < size) {
      if (std::chrono::steady_clock::now() > until) return false;
      const int n = socket_->Receive(p + got, size - got, 0);
      if (n == 0) {
        closed_ = true;
        return false;
      }
      if (n > 0) got += n;
    }
    return true;
  }

  std::optional<Received> receiveOne(std::chrono::steady_clock::time_point until) {
    auto header = igtl::MessageHeader::New();
    header->InitPack();
    if (!receiveExactly(header->GetPackPointer(), header->GetPackSize(), until)) {
      return std::nullopt;
    }
    header->Unpack();
    Received r;
    r.type = header->GetDeviceType();
    r.device = header->GetDeviceName();
    auto body = [&](auto m) {
      m->SetMessageHeader(header);
      m->AllocatePack();
      const bool ok = receiveExactly(m->GetPackBodyPointer(), m->GetPackBodySize(),
                                     until + std::chrono::seconds(1));
      EXPECT_TRUE(ok) << "body of " << r.type << " " << r.device;
      EXPECT_TRUE(m->Unpack(1) & igtl::MessageHeader::UNPACK_BODY) << "CRC of " << r.device;
      return m;
    };
    if (r.type == "STRING") {
      auto m = body(igtl::StringMessage::New());
      r.text = m->GetString();
    } else if (r.type == "STATUS") {
      auto m = body(igtl::StatusMessage::New());
      r.code = m->GetCode();
      r.error_name = m->GetErrorName();
      r.status_string = m->GetStatusString();
    } else if (r.type == "TRANSFORM") {
      auto m = body(igtl::TransformMessage::New());
      r.matrix = igtl_test::matrixOf(*m);
    } else {
      std::string skip(header->GetBodySizeToRead(), '\0');
      if (!skip.empty()) receiveExactly(skip.data(), static_cast<int>(skip.size()), until);
    }
    return r;
  }

  igtl::ClientSocket::Pointer socket_;
  bool connected_ = false;
  bool closed_ = false;
  std::set<std::string> ignore_;
  std::deque<Received> streamed_;
};

}  // namespace ignav::brp_test
