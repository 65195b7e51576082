// OpenIGTLink's framing in header versions 1 and 2 against code that is not ours: the version-3
// peer of the tests (v3_peer.hpp, written from the protocol's description), libOpenIGTLink's
// CRC-64 and its packing of version-1 messages, and the published CRC-64/ECMA-182 check value.
// Byte for byte: header, extended header, metadata header and metadata, CRC.
#include <gtest/gtest.h>

#include <random>

#include <igtlStatusMessage.h>
#include <igtlStringMessage.h>

#include "ignav/igtl/framing.hpp"
#include "ignav/igtl/message.hpp"
#include "v3_peer.hpp"

namespace ignav::igtl {
namespace {

using igtl3_test::be;
using igtl3_test::body2;
using igtl3_test::frame;
using igtl3_test::Meta;

std::vector<Expected<Message>> decodeAll(const std::string& stream, std::size_t chunk,
                                         std::size_t limit = 64 * 1024) {
  Decoder d(limit);
  std::vector<Expected<Message>> out;
  for (std::size_t i = 0; i < stream.size(); i += chunk) {
    d.feed(stream.data() + i, std::min(chunk, stream.size() - i));
    while (auto next = d.next())
      out.push_back(std::move(*next));
  }
  return out;
}

TEST(IgtlFraming, Crc64IsEcma182AsLibOpenIGTLinkComputesIt) {
  // The catalogue's check value of CRC-64/ECMA-182 (poly 42F0E1EBA9EA3693, init 0, no
  // reflection, no final XOR) over "123456789".
  EXPECT_EQ(crc64("123456789"), 0x6C40DF5F0B497347ULL);
  std::mt19937 random(7);
  for (std::size_t size : {0u, 1u, 7u, 58u, 4096u, 100001u}) {
    std::string bytes(size, '\0');
    for (auto& c : bytes)
      c = static_cast<char>(random());
    EXPECT_EQ(crc64(bytes), igtl3_test::referenceCrc(bytes)) << size << " bytes";
    // In two parts, continued, and combined from the parts' own CRCs.
    const std::size_t half = size / 3;
    EXPECT_EQ(crc64(bytes.substr(half), crc64(bytes.substr(0, half))), crc64(bytes));
    EXPECT_EQ(crc64Combine(crc64(bytes.substr(0, half)), crc64(bytes.substr(half)), size - half),
              crc64(bytes));
  }
}

TEST(IgtlFraming, TimestampsAreSecondsAndFractionsOfTwoToTheMinus32) {
  EXPECT_EQ(timestampOf(1.5), (1ULL << 32) | (1ULL << 31));
  EXPECT_EQ(timestampOf(1764441600.25), (1764441600ULL << 32) | (1ULL << 30));
  EXPECT_EQ(timestampOf(0), 0u);
  EXPECT_EQ(timestampOf(std::numeric_limits<double>::quiet_NaN()), 0u);
  EXPECT_NEAR(secondsOf(timestampOf(1764441600.123456)), 1764441600.123456, 1e-9);
}

TEST(IgtlFraming, AVersion1MessageIsWhatLibOpenIGTLinkPacks) {
  auto reference = ::igtl::StringMessage::New();
  reference->SetDeviceName("ACK_0001");
  reference->SetEncoding(3);
  reference->SetString("START_UP");
  reference->Pack();
  const std::string theirs(static_cast<const char*>(reference->GetPackPointer()),
                           static_cast<std::size_t>(reference->GetPackSize()));
  auto ours = encode(stringMessage("ACK_0001", "START_UP"));
  ASSERT_TRUE(ours.ok()) << ours.error().message;
  // Byte for byte but the timestamp (ours is the message's; theirs is the library's to set).
  ASSERT_EQ(ours->size(), theirs.size());
  EXPECT_EQ(ours->substr(0, 34), theirs.substr(0, 34));
  EXPECT_EQ(ours->substr(42), theirs.substr(42));
}

TEST(IgtlFraming, AVersion2MessageIsByteForByteTheProtocolsStructure) {
  Message m = stringMessage("ACK_0001", "START_UP");
  m.header_version = 2;
  m.message_id = 0x01020304;
  m.timestamp_s = 1764441600.5;
  m.metadata = {{"RobotId", kUsAscii, "torabi2014"}, {"Units", kUsAscii, "mm"}};
  auto ours = encode(m);
  ASSERT_TRUE(ours.ok()) << ours.error().message;
  const std::string expected = frame(2, "STRING", "ACK_0001", (1764441600ULL << 32) | (1ULL << 31),
                                     body2(igtl3_test::stringContent("START_UP"), 0x01020304,
                                           {{"RobotId", 3, "torabi2014"}, {"Units", 3, "mm"}}));
  EXPECT_EQ(*ours, expected);
  // The parts where the description puts them: extended header at 58, content at 70, the
  // metadata header after it (count 2, then key size, encoding, value size per entry).
  EXPECT_EQ(ours->substr(58, 2), be(12, 2));
  EXPECT_EQ(ours->substr(60, 2), be(2 + 8 * 2, 2));
  EXPECT_EQ(ours->substr(62, 4), be(7 + 10 + 5 + 2, 4));
  EXPECT_EQ(ours->substr(66, 4), be(0x01020304, 4));
  EXPECT_EQ(ours->substr(70, 12), be(3, 2) + be(8, 2) + "START_UP");
  EXPECT_EQ(ours->substr(82, 2), be(2, 2));
  EXPECT_EQ(ours->substr(84, 8), be(7, 2) + be(3, 2) + be(10, 4));
  EXPECT_EQ(ours->substr(100), "RobotIdtorabi2014Unitsmm");
}

TEST(IgtlFraming, ACommandIsItsFixedPartAndItsText) {
  Message m = commandMessage("RTS_COMMAND", 42, "START_UP", "<Command><Result>true</Result>");
  m.message_id = 9;
  auto ours = encode(m);
  ASSERT_TRUE(ours.ok()) << ours.error().message;
  EXPECT_EQ(
      *ours,
      frame(2, "RTS_COMMAND", "COMMAND", 0,
            body2(igtl3_test::commandContent(42, "START_UP", "<Command><Result>true</Result>"), 9,
                  {})));
  EXPECT_FALSE(encode(commandMessage("COMMAND", 1, std::string(128, 'n'), "")).ok());
  EXPECT_TRUE(encode(commandMessage("COMMAND", 1, std::string(127, 'n'), "")).ok());
}

TEST(IgtlFraming, WhatThePeerSendsIsReadSplitAnywhere) {
  const float pose[3][4] = {{1, 0, 0, 10.5f}, {0, 1, 0, -20.25f}, {0, 0, 1, 30}};
  const std::string stream =
      frame(2, "STRING", "CMD_0001", (5ULL << 32),
            body2(igtl3_test::stringContent("START_UP"), 1, {{"Sender", 3, "Slicer"}})) +
      frame(2, "TRANSFORM", "CLB_0002", 0,
            body2(igtl3_test::transformContent(pose), 2, {{"Units", 3, "mm"}, {"", 3, ""}})) +
      frame(2, "COMMAND", "COMMAND", 0,
            body2(igtl3_test::commandContent(77, "Get", "<Command Name=\"Get\" />"), 3, {})) +
      frame(1, "GET_STATUS", "", 0, "");
  for (std::size_t chunk : {1u, 5u, 58u, 71u, 4096u}) {
    const auto messages = decodeAll(stream, chunk);
    ASSERT_EQ(messages.size(), 4u) << "chunk " << chunk;
    for (const auto& m : messages)
      ASSERT_TRUE(m.ok()) << m.error().message;
    const Message& s = messages[0].value();
    EXPECT_EQ(s.header_version, 2);
    EXPECT_EQ(s.message_id, 1u);
    EXPECT_EQ(s.text, "START_UP");
    EXPECT_EQ(s.timestamp_s, 5.0);
    ASSERT_EQ(s.metadata.size(), 1u);
    EXPECT_EQ(s.metadata[0], (MetaDataEntry{"Sender", kUsAscii, "Slicer"}));
    const Message& t = messages[1].value();
    EXPECT_EQ(t.device_name, "CLB_0002");
    EXPECT_EQ(t.matrix(1, 3), -20.25);
    ASSERT_EQ(t.metadata.size(), 2u);
    EXPECT_EQ(t.metadata[1].key, "");  // an empty key and value are still an entry
    const Message& c = messages[2].value();
    EXPECT_EQ(c.type, "COMMAND");
    EXPECT_EQ(c.command.id, 77u);
    EXPECT_EQ(c.command.name, "Get");
    EXPECT_EQ(c.command.text, "<Command Name=\"Get\" />");
    EXPECT_EQ(messages[3].value().header_version, 1);
    EXPECT_EQ(messages[3].value().type, "GET_STATUS");
  }
}

// A version-2 body whose extended header says `ext`, `meta_header`, `meta` sizes (not the truth).
std::string lyingBody(std::uint16_t ext, std::uint16_t meta_header, std::uint32_t meta,
                      const std::string& rest) {
  return be(ext, 2) + be(meta_header, 2) + be(meta, 4) + be(1, 4) + rest;
}

TEST(IgtlFraming, InconsistentSizesAreRefusedByNameAndTheStreamGoesOn) {
  const std::string good =
      frame(2, "STRING", "CMD_9", 0, body2(igtl3_test::stringContent("STOP"), 2, {}));
  const std::string content = igtl3_test::stringContent("START_UP");
  struct Case {
    const char* what;
    std::string bytes;
    const char* named;
  } cases[] = {
      {"short body", frame(2, "STRING", "CMD_1", 0, "abc"), "extended header"},
      {"extended header size 4", frame(2, "STRING", "CMD_1", 0, lyingBody(4, 2, 0, content)),
       "extended header size 4"},
      {"sizes past the body",
       frame(2, "STRING", "CMD_1", 0, lyingBody(12, 2, 0xffffffffu, content + be(0, 2))),
       "exceed the body"},
      {"metadata header not 2 + 8n",
       frame(2, "STRING", "CMD_1", 0, lyingBody(12, 9, 0, content + be(1, 2) + "1234567")),
       "metadata header size 9"},
      {"count disagrees with the header size",
       frame(2, "STRING", "CMD_1", 0, lyingBody(12, 2, 0, content + be(3, 2))),
       "metadata header size 2"},
      {"an entry past the metadata",
       frame(2, "STRING", "CMD_1", 0,
             lyingBody(12, 10, 4, content + be(1, 2) + be(3, 2) + be(3, 2) + be(9, 4) + "abcd")),
       "runs past"},
      {"metadata without a header",
       frame(2, "STRING", "CMD_1", 0, lyingBody(12, 0, 4, content + "abcd")),
       "without a metadata header"},
      {"command shorter than its fixed part",
       frame(2, "COMMAND", "COMMAND", 0, body2(std::string(20, 'x'), 1, {})), "fixed part"},
      {"command name without its NUL",
       frame(2, "COMMAND", "COMMAND", 0,
             body2(be(1, 4) + std::string(128, 'n') + be(3, 2) + be(0, 4), 1, {})),
       "NUL-terminated"},
      {"command text past its body",
       frame(2, "COMMAND", "COMMAND", 0,
             body2(be(1, 4) + std::string(128, '\0') + be(3, 2) + be(1000, 4) + "x", 1, {})),
       "exceeds"},
  };
  for (const auto& c : cases) {
    for (std::size_t chunk : {1u, 13u, 1000u}) {
      const auto messages = decodeAll(c.bytes + good, chunk);
      ASSERT_EQ(messages.size(), 2u) << c.what;
      ASSERT_FALSE(messages[0].ok()) << c.what;
      EXPECT_NE(messages[0].error().message.find(c.named), std::string::npos)
          << c.what << ": " << messages[0].error().message;
      ASSERT_TRUE(messages[1].ok()) << c.what << ": " << messages[1].error().message;
      EXPECT_EQ(messages[1].value().text, "STOP") << c.what;
    }
  }
}

TEST(IgtlFraming, AHeaderAnnouncingAnEnormousBodyIsRefusedAndNothingIsHeld) {
  // A 58-byte header whose body size is 2^64 - 1: refused at once, and its "body" skipped.
  std::string header = frame(2, "STRING", "CMD_1", 0, "");
  header.replace(42, 8, be(~0ULL, 8));
  Decoder d(4096);
  d.feed(header.data(), header.size());
  auto next = d.next();
  ASSERT_TRUE(next.has_value());
  ASSERT_FALSE(next->ok());
  EXPECT_NE(next->error().message.find("18446744073709551615"), std::string::npos)
      << next->error().message;
  const std::string more(100000, 'x');
  d.feed(more.data(), more.size());
  EXPECT_EQ(d.buffered(), 0u);
  EXPECT_FALSE(d.next().has_value());
}

TEST(IgtlFraming, ACorruptVersion2BodyFailsItsCrc) {
  std::string bytes =
      frame(2, "STRING", "CMD_1", 0, body2(igtl3_test::stringContent("START_UP"), 1, {}));
  bytes.back() ^= 1;
  const auto messages = decodeAll(bytes, 1000);
  ASSERT_EQ(messages.size(), 1u);
  ASSERT_FALSE(messages[0].ok());
  EXPECT_NE(messages[0].error().message.find("CRC"), std::string::npos);
}

}  // namespace
}  // namespace ignav::igtl
