// The reply topics over real Cyclone DDS on loopback (domain 106): a client keeps its own replies
// only, and replies are keyed by client, not by request; a removed target's instance leaves the
// server's writer (docs/RELIABILITY.md, L1 to L3).
#include <gtest/gtest.h>

#include <chrono>
#include <functional>
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

// A removed target is disposed and unregistered: a viewer present sees it disposed, and the
// writer forgets it, so a viewer that joins later is sent neither it nor its disposal. Disposed
// only, every target ever removed stayed in the server's writer for good, and a late joiner was
// sent the disposal of each (docs/RELIABILITY.md L3).
TEST(Targets, ARemovedTargetIsDisposedAndForgottenByTheWriter) {
  const std::string xml = readConfigFile(IGNAV_SOURCE_DIR "/configs/dds/loopback.xml");
  Participant server(106, xml, nullptr, "robot-1");
  Participant client(106, xml, nullptr, "robot-1");
  Writer<ignav_msg_TargetState> targets(server, &ignav_msg_TargetState_desc, topic::kTarget,
                                        Qos::kState);
  struct Seen {
    std::vector<std::uint32_t> alive, disposed;
  };
  auto collect = [](const Reader<ignav_msg_TargetState>& reader, Seen& seen) {
    reader.takeWithState([&](const ignav_msg_TargetState& t, bool alive) {
      (alive ? seen.alive : seen.disposed).push_back(t.id);
    });
  };
  // Collects until `done` holds, for a second at most.
  auto collectUntil = [&](const Reader<ignav_msg_TargetState>& reader, Seen& seen,
                          const std::function<bool()>& done) {
    for (int i = 0; i < 200 && !done(); ++i) {
      collect(reader, seen);
      std::this_thread::sleep_for(5ms);
    }
  };
  const std::string text = "x";
  auto sample = [&](std::uint32_t id) {
    ignav_msg_TargetState t{};
    t.id = id;
    t.reach = t.message = cstr(text);
    return t;
  };
  Seen present;
  {
    Reader<ignav_msg_TargetState> viewer(client, &ignav_msg_TargetState_desc, topic::kTarget,
                                         Qos::kState);
    for (int i = 0; i < 500 && targets.matched() < 1; ++i)
      std::this_thread::sleep_for(10ms);
    ASSERT_EQ(targets.matched(), 1u);
    for (std::uint32_t id = 1; id <= 3; ++id)
      targets.write(sample(id));
    collectUntil(viewer, present, [&] { return present.alive.size() >= 3; });
    targets.dispose(sample(1));
    targets.dispose(sample(2));
    collectUntil(viewer, present, [&] { return present.disposed.size() >= 2; });
  }
  EXPECT_EQ(present.alive, (std::vector<std::uint32_t>{1, 2, 3}));
  EXPECT_EQ(present.disposed, (std::vector<std::uint32_t>{1, 2}));

  Reader<ignav_msg_TargetState> late(client, &ignav_msg_TargetState_desc, topic::kTarget,
                                     Qos::kState);
  Seen joined;
  collectUntil(late, joined, [&] { return !joined.alive.empty(); });
  std::this_thread::sleep_for(200ms);  // anything more the writer would send has come by now
  collect(late, joined);
  EXPECT_EQ(joined.alive, (std::vector<std::uint32_t>{3}));
  EXPECT_TRUE(joined.disposed.empty());
}

}  // namespace
}  // namespace ignav::protocol
