// The reply topics over real Cyclone DDS on loopback (domain 106): a client keeps its own replies
// only, and replies are keyed by client, not by request (docs/RELIABILITY.md, L1 and L2).
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "ignav/protocol/wire/dds.hpp"
#include "ignav/protocol/wire/messages.hpp"

namespace ignav::protocol {
namespace {

using namespace std::chrono_literals;

bool toA(const void* sample, void*) {
  const char* id = static_cast<const ignav_msg_Reply*>(sample)->client_id;
  return id && std::string(id) == "a";
}

TEST(Replies, AFilteredReaderStoresItsOwnRepliesOnly) {
  const std::string xml = readConfigFile(IGNAV_SOURCE_DIR "/configs/dds/loopback.xml");
  Participant server(106, xml, nullptr, "robot-1");
  Participant client(106, xml, nullptr, "robot-1");
  Writer<ignav_msg_Reply> replies(server, &ignav_msg_Reply_desc, topic::kReply, Qos::kRequest);
  Reader<ignav_msg_Reply> mine(client, &ignav_msg_Reply_desc, topic::kReply, Qos::kRequest, &toA,
                               nullptr);
  Reader<ignav_msg_Reply> all(client, &ignav_msg_Reply_desc, topic::kReply, Qos::kRequest);
  for (int i = 0; i < 500 && (replies.matched() < 2); ++i)
    std::this_thread::sleep_for(10ms);
  ASSERT_EQ(replies.matched(), 2u);
  const std::string a = "a", b = "b";
  for (std::uint64_t r = 1; r <= 10; ++r) {
    ignav_msg_Reply reply{};
    reply.client_id = cstr(r % 2 ? a : b);
    reply.request_id = r;
    reply.error_code = reply.message = cstr(a);
    replies.write(reply);
  }
  std::vector<std::uint64_t> taken_mine, taken_all;
  for (int i = 0; i < 200 && taken_all.size() < 10; ++i) {
    mine.take([&](const ignav_msg_Reply& r) { taken_mine.push_back(r.request_id); });
    all.take([&](const ignav_msg_Reply& r) { taken_all.push_back(r.request_id); });
    std::this_thread::sleep_for(5ms);
  }
  mine.take([&](const ignav_msg_Reply& r) { taken_mine.push_back(r.request_id); });
  EXPECT_EQ(taken_all.size(), 10u);  // all arrived
  EXPECT_EQ(taken_mine, (std::vector<std::uint64_t>{1, 3, 5, 7, 9}));
}

// Keyed per request, every reply left an instance in the server's writer for good (~1 KiB per
// command, measured with tools/bench/bench_load.sh and heaptrack).
TEST(Replies, AreKeyedByClientOnly) {
  EXPECT_EQ(ignav_msg_Reply_desc.m_nkeys, 1u);
  EXPECT_EQ(std::string(ignav_msg_Reply_desc.m_keys[0].m_name), "client_id");
  EXPECT_EQ(ignav_msg_SliceReply_desc.m_nkeys, 1u);
  EXPECT_EQ(std::string(ignav_msg_SliceReply_desc.m_keys[0].m_name), "client_id");
}

}  // namespace
}  // namespace ignav::protocol
