// The slices clients ask for are drawn on the server's slices thread (issue 22.2): commands are
// answered while another client asks for the largest slices, and a burst beyond the bounded queue
// is refused at once, every request answered exactly once. Real ignav-server processes over
// Cyclone DDS on loopback; domains 122-123.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "ignav/protocol/wire/messages.hpp"
#include "server_process.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

std::string text(const char* s) {
  return s ? s : "";
}

void loadPhantom(protocol::Client& c) {
  ASSERT_TRUE(c.send("load_volume", {"phantom:", {}, {}}).accepted);
  c.waitFor([](const json& s) { return stateText(s, "volume", "status") == "loaded"; }, 60s);
  ASSERT_EQ(stateText(c.state(), "volume", "status"), "loaded");
}

TEST(SlicesE2E, CommandsAreAnsweredAtOnceWhileAnotherClientAsksForTheLargestSlices) {
  ServerProcess server(122);
  auto op = server.client("operator");
  loadPhantom(*op);
  std::atomic<int> drawn{0};
  std::mutex slices_mutex;
  std::vector<double> slice_ms;  // each slice's round trip, as the viewer saw it
  LoopInBackground viewer([&](const std::atomic<bool>& busy) {
    auto v = server.client("viewer");
    protocol::SliceArgs big;
    big.size_px = 2048;  // the largest allowed: about 0.2 s each in RelWithDebInfo
    while (busy) {
      const auto t = Clock::now();
      const auto s = v->slice(big, 30s);
      const double ms = msOf(Clock::now() - t);
      if (!s.ok) continue;
      {
        std::lock_guard<std::mutex> lock(slices_mutex);
        slice_ms.push_back(ms);
      }
      ++drawn;
    }
  });
  while (drawn == 0)
    std::this_thread::sleep_for(10ms);
  // Another client's queries, every 20 ms, each timed: for 3 s, and on until the viewer has drawn
  // 3 more slices, however long that takes in this build on this machine (beyond 120 s the viewer
  // has stopped).
  auto watcher = server.client("watcher");
  std::vector<double> query_ms;
  const int drawn_before = drawn;
  const auto start = Clock::now();
  while (Clock::now() < start + 3s || (drawn < drawn_before + 3 && Clock::now() < start + 120s)) {
    const auto t = Clock::now();
    EXPECT_TRUE(watcher->send("query", {}, 20s).accepted);
    query_ms.push_back(msOf(Clock::now() - t));
    std::this_thread::sleep_for(20ms);
  }
  const int drawn_meanwhile = drawn - drawn_before;
  std::vector<double> slices;
  {
    std::lock_guard<std::mutex> lock(slices_mutex);
    slices = slice_ms;
  }
  std::sort(slices.begin(), slices.end());
  std::sort(query_ms.begin(), query_ms.end());
  const double slice_median = slices[slices.size() / 2];
  const double median = query_ms[query_ms.size() / 2];
  const double p90 = query_ms[query_ms.size() * 9 / 10];
  std::cout << slices.size() << " slices of 2048² (median " << slice_median << " ms, slowest "
            << slices.back() << " ms); " << query_ms.size() << " queries: median " << median
            << " ms, p90 " << p90 << " ms, worst " << query_ms.back() << " ms" << std::endl;
  EXPECT_GE(drawn_meanwhile, 3);
  ASSERT_GT(query_ms.size(), 10u);
  // When the event thread drew them, a query waited for the rest of the slice being drawn: half
  // a slice in the middle, a whole one at worst. Against the slices' own time, whatever it is on
  // this machine and build; the typical slice, as one slow one would loosen the bound. (The worst
  // query is not bounded here: on two shared cores the slices thread, the viewer and the watcher
  // compete for them.)
  EXPECT_LT(median, 0.25 * slice_median) << "queries waited behind the slices";
}

TEST(SlicesE2E, ABurstBeyondTheQueueIsRefusedAtOnceAndEveryRequestIsAnsweredOnce) {
  ServerProcess server(123);
  auto op = server.client("operator");
  loadPhantom(*op);
  protocol::Participant p(server.domain(), loopbackXml(), nullptr, server.robotId());
  protocol::Writer<ignav_msg_SliceRequest> requests(
      p, &ignav_msg_SliceRequest_desc, protocol::topic::kSliceRequest, protocol::Qos::kRequest);
  protocol::Reader<ignav_msg_SliceReply> replies(
      p, &ignav_msg_SliceReply_desc, protocol::topic::kSliceReply, protocol::Qos::kRequest);
  for (int i = 0; i < 500 && (requests.matched() == 0 || replies.matched() == 0); ++i)
    std::this_thread::sleep_for(10ms);
  ASSERT_GT(requests.matched(), 0u);
  // Fewer than the request topic keeps (64), more than the server's queue (32).
  constexpr std::uint64_t kBurst = 60;
  const std::string client = "burst", view = "axial";
  for (std::uint64_t id = 1; id <= kBurst; ++id) {
    ignav_msg_SliceRequest r{};
    r.client_id = protocol::cstr(client);
    r.request_id = id;
    r.view = protocol::cstr(view);
    r.size_px = 512;
    requests.write(r);
  }
  std::map<std::uint64_t, int> answers;
  std::vector<std::uint64_t> drawn;  // in the order they came
  std::size_t busy = 0;
  const auto end = Clock::now() + (kSanitized ? 120s : 60s);
  while (answers.size() < kBurst && Clock::now() < end) {
    replies.take([&](const ignav_msg_SliceReply& r) {
      if (text(r.client_id) != client) return;
      ++answers[r.request_id];
      if (r.ok) {
        drawn.push_back(r.request_id);
      } else {
        EXPECT_NE(text(r.message).find("busy"), std::string::npos) << r.message;
        ++busy;
      }
    });
    std::this_thread::sleep_for(5ms);
  }
  EXPECT_EQ(answers.size(), kBurst);
  for (const auto& [id, n] : answers)
    EXPECT_EQ(n, 1) << "request " << id;
  // At least the queue's worth drawn, in the order asked; the rest refused (some may fit in as
  // slices finish while the burst is taken).
  EXPECT_GE(drawn.size(), 32u);
  EXPECT_GT(busy, 0u);
  EXPECT_TRUE(std::is_sorted(drawn.begin(), drawn.end()));
  EXPECT_EQ(drawn.front(), 1u);
  // The server goes on: a slice and a query after the burst.
  auto v = server.client("viewer");
  protocol::SliceArgs small;
  small.size_px = 64;
  EXPECT_TRUE(v->slice(small).ok);
  EXPECT_TRUE(op->send("query").accepted);
}

}  // namespace
}  // namespace ignav::e2e
