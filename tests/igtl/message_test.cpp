// The OpenIGTLink codec against libOpenIGTLink (an implementation that is not ours): what we
// encode it reads, with its CRC check; what it packs we decode, split at any byte. Bad streams
// cost one message, not the connection.
#include <gtest/gtest.h>

#include <cstring>

#include <igtlMessageHeader.h>
#include <igtlPointMessage.h>
#include <igtlStatusMessage.h>
#include <igtlStringMessage.h>
#include <igtlTransformMessage.h>
#include <Eigen/Geometry>

#include "ignav/igtl/message.hpp"
#include "igtl_readback.hpp"

namespace ignav::igtl {
namespace {

using igtl_test::packed;
using igtl_test::readBack;

std::vector<Message> decodeAll(const std::string& stream, std::size_t chunk) {
  Decoder d;
  std::vector<Message> out;
  for (std::size_t i = 0; i < stream.size(); i += chunk) {
    d.feed(stream.data() + i, std::min(chunk, stream.size() - i));
    while (auto next = d.next()) {
      EXPECT_TRUE(next->ok()) << next->error().message;
      if (next->ok()) out.push_back(next->value());
    }
  }
  return out;
}

TEST(IgtlCodec, WhatWeEncodeLibOpenIGTLinkReads) {
  auto s = encode(statusMessage("CURRENT_STATUS", StatusCode::kManualMode, "MANUAL", "manual"));
  ASSERT_TRUE(s.ok()) << s.error().message;
  auto status = readBack<::igtl::StatusMessage>(*s);
  EXPECT_STREQ(status->GetDeviceName(), "CURRENT_STATUS");
  EXPECT_EQ(status->GetCode(), 14);
  EXPECT_STREQ(status->GetErrorName(), "manual");
  EXPECT_STREQ(status->GetStatusString(), "MANUAL");

  auto t = encode(stringMessage("ACK_0001", "MOVE_TO_TARGET"));
  ASSERT_TRUE(t.ok());
  auto text = readBack<::igtl::StringMessage>(*t);
  EXPECT_STREQ(text->GetDeviceName(), "ACK_0001");
  EXPECT_STREQ(text->GetString(), "MOVE_TO_TARGET");

  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  m.topRightCorner<3, 1>() << 12.25, -40.5, 101.125;
  auto x = encode(transformMessage("ImageToRobot", m));
  ASSERT_TRUE(x.ok());
  auto transform = readBack<::igtl::TransformMessage>(*x);
  ::igtl::Matrix4x4 f;
  transform->GetMatrix(f);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      EXPECT_EQ(f[r][c], static_cast<float>(m(r, c))) << r << "," << c;

  Message points;
  points.type = "POINT";
  points.device_name = "ACK_F";
  points.points.push_back({"F-1", "TARGET", Eigen::Vector3d(1.5, -2.25, 30)});
  auto p = encode(points);
  ASSERT_TRUE(p.ok());
  auto point = readBack<::igtl::PointMessage>(*p);
  ASSERT_EQ(point->GetNumberOfPointElement(), 1);
  ::igtl::PointElement::Pointer e;
  point->GetPointElement(0, e);
  float xyz[3];
  e->GetPosition(xyz);
  EXPECT_STREQ(e->GetName(), "F-1");
  EXPECT_EQ(xyz[0], 1.5f);
  EXPECT_EQ(xyz[1], -2.25f);
  EXPECT_EQ(xyz[2], 30.0f);
}

TEST(IgtlCodec, WhatLibOpenIGTLinkPacksWeDecodeSplitAnywhere) {
  auto cmd = ::igtl::StringMessage::New();
  cmd->SetDeviceName("CMD_0042");
  cmd->SetString("TARGETING");
  auto tgt = ::igtl::TransformMessage::New();
  tgt->SetDeviceName("TGT_0043");
  ::igtl::Matrix4x4 f;
  ::igtl::IdentityMatrix(f);
  f[0][3] = -12.5f;
  f[1][3] = 33.25f;
  f[2][3] = -80.0f;
  tgt->SetMatrix(f);
  auto get = ::igtl::GetStatusMessage::New();
  get->SetDeviceName("");
  auto where = ::igtl::GetTransformMessage::New();
  where->SetDeviceName("CURRENT_POSITION");
  const std::string stream = packed(cmd) + packed(tgt) + packed(get) + packed(where);
  for (std::size_t chunk : {1u, 7u, 58u, 1000u}) {
    const auto messages = decodeAll(stream, chunk);
    ASSERT_EQ(messages.size(), 4u) << "chunk " << chunk;
    EXPECT_EQ(messages[0].type, "STRING");
    EXPECT_EQ(messages[0].device_name, "CMD_0042");
    EXPECT_EQ(messages[0].text, "TARGETING");
    EXPECT_EQ(messages[1].type, "TRANSFORM");
    EXPECT_EQ(Eigen::Vector3d(messages[1].matrix.topRightCorner<3, 1>()),
              Eigen::Vector3d(-12.5, 33.25, -80.0));
    EXPECT_EQ(messages[2].type, "GET_STATUS");
    EXPECT_EQ(messages[3].type, "GET_TRANS");  // OpenIGTLink's GET_TRANSFORM
    EXPECT_EQ(messages[3].device_name, "CURRENT_POSITION");
  }
}

TEST(IgtlCodec, ACorruptMessageIsAnErrorAndTheStreamGoesOn) {
  auto cmd = ::igtl::StringMessage::New();
  cmd->SetDeviceName("CMD_1");
  cmd->SetString("START_UP");
  std::string bad = packed(cmd);
  bad.back() ^= 0x20;  // a flipped bit in the body: the CRC no longer matches
  auto good = ::igtl::StringMessage::New();
  good->SetDeviceName("CMD_2");
  good->SetString("PLANNING");
  Decoder d;
  const std::string stream = bad + packed(good);
  d.feed(stream.data(), stream.size());
  auto first = d.next();
  ASSERT_TRUE(first.has_value());
  ASSERT_FALSE(first->ok());
  EXPECT_NE(first->error().message.find("CMD_1"), std::string::npos) << first->error().message;
  auto second = d.next();
  ASSERT_TRUE(second.has_value() && second->ok());
  EXPECT_EQ(second->value().text, "PLANNING");
}

TEST(IgtlCodec, AnOversizedBodyIsRefusedAndSkipped) {
  auto big = ::igtl::StringMessage::New();
  big->SetDeviceName("CMD_BIG");
  big->SetString(std::string(60000, 'x').c_str());
  auto good = ::igtl::StringMessage::New();
  good->SetDeviceName("CMD_2");
  good->SetString("STOP");
  Decoder d(1024);  // a 1 KiB body limit
  const std::string stream = packed(big) + packed(good);
  std::vector<std::string> errors, texts;
  for (std::size_t i = 0; i < stream.size(); i += 4096) {
    d.feed(stream.data() + i, std::min<std::size_t>(4096, stream.size() - i));
    while (auto next = d.next()) {
      if (next->ok()) {
        texts.push_back(next->value().text);
      } else {
        errors.push_back(next->error().message);
      }
    }
    EXPECT_LE(d.buffered(), 4096u + kHeaderBytes);  // the refused body is not held
  }
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("CMD_BIG"), std::string::npos) << errors[0];
  EXPECT_EQ(texts, std::vector<std::string>{"STOP"});
}

TEST(IgtlCodec, AnotherHeaderVersionIsReportedAsSuch) {
  auto cmd = ::igtl::StringMessage::New();
  cmd->SetDeviceName("CMD_1");
  cmd->SetString("START_UP");
  std::string bytes = packed(cmd);
  bytes[1] = 3;  // header version 3
  Decoder d;
  d.feed(bytes.data(), bytes.size());
  auto next = d.next();
  ASSERT_TRUE(next.has_value());
  ASSERT_FALSE(next->ok());
  EXPECT_EQ(next->error().reason, "header_version");
}

TEST(IgtlCodec, EncodingRefusesWhatTheWireCannotCarry) {
  auto long_name = encode(stringMessage("A_DEVICE_NAME_OVER_20_CHARACTERS", "x"));
  ASSERT_FALSE(long_name.ok());
  EXPECT_NE(long_name.error().message.find("A_DEVICE_NAME_OVER_20"), std::string::npos);
  // libOpenIGTLink reads a 20-character error name without a terminator: at most 19 go out.
  EXPECT_TRUE(encode(statusMessage("X", StatusCode::kOk, "", std::string(19, 'e'))).ok());
  Message twenty = statusMessage("X", StatusCode::kOk);
  twenty.status.error_name = std::string(20, 'e');  // statusMessage itself cuts it to 19
  EXPECT_FALSE(encode(twenty).ok());
  EXPECT_EQ(statusMessage("X", StatusCode::kOk, "", std::string(25, 'e')).status.error_name,
            std::string(19, 'e'));
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(encode(transformMessage("X", m)).ok());
}

}  // namespace
}  // namespace ignav::igtl
