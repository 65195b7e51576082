// The gateway between a real ignav-server (its own process, real Cyclone DDS on loopback) and
// WebSocket/HTTP clients written here with Boost.Beast, as a browser would talk to it.
#include "gateway.hpp"

#include "browser_socket.hpp"

#include <gtest/gtest.h>

#include <boost/asio.hpp>
#include <boost/beast.hpp>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "e2e/server_process.hpp"

namespace ignav::web {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = asio::ip::tcp;
using nlohmann::json;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

// A gateway served from a thread of the test.
class RunningGateway {
 public:
  RunningGateway(std::uint32_t domain, const std::string& client_id = "operator",
                 std::optional<protocol::SecurityIdentity> identity = std::nullopt) {
    GatewayOptions o;
    o.identity = std::move(identity);
    o.port = 0;
    o.app_dir = IGNAV_SOURCE_DIR "/tests/web/app_fixture";
    o.domain = domain;
    o.dds_config_xml = e2e::loopbackXml();
    o.client_id = client_id;
    o.robot_id = "robot-1";  // configs/server.yaml's, which the tests' servers use
    gateway_ = std::make_unique<Gateway>(o);
    thread_ = std::thread([this] { gateway_->run(); });
  }
  ~RunningGateway() {
    gateway_->stop();
    thread_.join();
  }
  std::uint16_t port() const { return gateway_->port(); }

 private:
  std::unique_ptr<Gateway> gateway_;
  std::thread thread_;
};

using Browser = BrowserSocket;

http::response<http::string_body> httpGet(std::uint16_t port, const std::string& target) {
  asio::io_context io;
  beast::tcp_stream stream(io);
  tcp::resolver resolver(io);
  stream.connect(*resolver.resolve("127.0.0.1", std::to_string(port)));
  http::request<http::empty_body> req(http::verb::get, target, 11);
  req.set(http::field::host, "127.0.0.1");
  http::write(stream, req);
  beast::flat_buffer buffer;
  http::response<http::string_body> res;
  http::read(stream, buffer, res);
  return res;
}

json command(const std::string& kind, json extra = json::object()) {
  extra["op"] = "command";
  extra["kind"] = kind;
  return extra;
}

// Until the gateway has matched every endpoint of the server (it says so in a "connection"
// message, or already in its hello): the first state sample can come before that, and secure
// discovery under the sanitizers takes a while.
void waitForServer(Browser& tab, const json& hello) {
  if (hello.value("server", false)) return;
  for (json m = tab.next(); !(m["type"] == "connection" && m["server"] == true); m = tab.next()) {
  }
}

TEST(Gateway, BrowserDrivesTheServerAndSeesItsVerdicts) {
  e2e::ServerProcess server(110);
  RunningGateway gateway(110);
  Browser tab(gateway.port());
  const json hello = tab.next();
  EXPECT_EQ(hello["type"], "hello");
  EXPECT_EQ(hello["client_id"], "operator");
  EXPECT_EQ(hello["security"], false);
  // Without DDS Security every command may be published (the server still judges each).
  for (const char* command : {"add_target", "lock_plan", "approve", "reset_emergency"}) {
    EXPECT_NE(std::find(hello["permitted"].begin(), hello["permitted"].end(), command),
              hello["permitted"].end())
        << command;
  }
  waitForServer(tab, hello);
  tab.waitState([](const json& s) { return s.contains("workflow"); });
  EXPECT_EQ(tab.state()["workflow"]["phase"], "imaging");
  // The closed loop's topic (issue 23) reaches browsers as every other does: nothing measured.
  tab.waitState([](const json& s) { return s.contains("verification"); });
  EXPECT_EQ(tab.state()["verification"]["status"], "none");
  EXPECT_TRUE(tab.state()["verification"]["targets"].empty());

  // A command the workflow refuses comes back as the server's reply, not a gateway error.
  const json early = tab.request(command("add_target", {{"points", {{1, 2, 3}}}}));
  EXPECT_EQ(early["type"], "reply");
  EXPECT_EQ(early["accepted"], false);
  EXPECT_EQ(early["error_code"], "wrong_phase") << early;

  // Bad input: refused by the gateway with the field named; the connection stays usable.
  tab.sendText("{\"op\":\"command\",\"seq\":500,\"kind\":\"add_target\",\"points\":[[1,2]]}");
  const json bad = tab.until("error", 500);
  EXPECT_EQ(bad["code"], "bad_request");
  EXPECT_NE(bad["message"].get<std::string>().find("points[0]"), std::string::npos);
  tab.sendText("\xff\xfe not even text");  // a text frame that is not UTF-8 fails the socket
  Browser tab2(gateway.port());            // ... and a new tab still works

  // The background work a command starts ends in its job's outcome (on the JobOutcome topic,
  // passed to every browser).
  const json load = tab2.request(command("load_volume", {{"path", "phantom:"}}));
  ASSERT_EQ(load["accepted"], true) << load;
  ASSERT_GT(load["job"].get<std::uint64_t>(), 0u) << load;
  const json loaded = tab2.jobOutcome(load["job"]);
  EXPECT_EQ(loaded["kind"], "CT load");
  EXPECT_EQ(loaded["input"], "volume_loaded");
  EXPECT_EQ(loaded["status"], "done") << loaded;
  tab2.waitState(
      [](const json& s) { return s.contains("volume") && s["volume"]["status"] == "loaded"; });
  const json fid = tab2.request(command("auto_fiducials"));
  ASSERT_EQ(fid["accepted"], true) << fid;
  EXPECT_EQ(tab2.jobOutcome(fid["job"])["status"], "done");
  tab2.waitState([](const json& s) {
    return s.contains("registration") && s["registration"]["status"] == "registered" &&
           s["workflow"]["phase"] == "planning";
  });

  // A reachable target, placed where the registration puts robot point (8, 12, -175).
  const Eigen::Vector3d lps = e2e::lpsOf(tab2.state(), {8.0, 12.0, -175.0});
  const json added =
      tab2.request(command("add_target", {{"points", {{lps.x(), lps.y(), lps.z()}}}}));
  ASSERT_EQ(added["accepted"], true) << added;
  const std::string id = std::to_string(added["target_id"].get<int>());
  tab2.waitState([&](const json& s) { return s.contains("targets") && s["targets"].contains(id); });
  const json target = tab2.state()["targets"][id];
  EXPECT_TRUE(target["reachable"].get<bool>());
  // The planned path ends at the target (the server's forward kinematics, checked here against
  // the click).
  ASSERT_GE(target["path_lps"].size(), 2u);
  const json tip = target["path_lps"].back();
  EXPECT_LT((Eigen::Vector3d(tip[0], tip[1], tip[2]) - lps).norm(), 1e-3);

  // A slice through the target: a real PNG of the size announced, and a pixel -> LPS mapping
  // that puts the centre pixel at the requested centre.
  const json slice = tab2.request({{"op", "slice"},
                                   {"view", "axial"},
                                   {"centre_lps", {lps.x(), lps.y(), lps.z()}},
                                   {"size_px", 128},
                                   {"pixel_mm", 0.5},
                                   {"overlays", "region"}});
  ASSERT_EQ(slice["type"], "slice");
  ASSERT_EQ(slice["ok"], true) << slice["message"];
  EXPECT_EQ(slice["width"], 128);
  // Decoded by hand, not with the OpenSSL routine the gateway encodes with.
  const std::string b64 = slice["png_base64"];
  std::vector<std::uint8_t> png;
  {
    auto value = [](char c) -> int {
      if (c >= 'A' && c <= 'Z') return c - 'A';
      if (c >= 'a' && c <= 'z') return c - 'a' + 26;
      if (c >= '0' && c <= '9') return c - '0' + 52;
      return c == '+' ? 62 : c == '/' ? 63 : -1;
    };
    std::uint32_t acc = 0;
    int bits = 0;
    for (const char c : b64) {
      const int v = value(c);
      if (v < 0) break;
      acc = (acc << 6) | static_cast<std::uint32_t>(v);
      bits += 6;
      if (bits >= 8) {
        bits -= 8;
        png.push_back(static_cast<std::uint8_t>((acc >> bits) & 0xff));
      }
    }
  }
  const cv::Mat image = cv::imdecode(png, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 128);
  EXPECT_EQ(image.rows, 128);
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i)
    m(i / 4, i % 4) = slice["pixel_to_lps"][static_cast<std::size_t>(i)];
  // docs/PROTOCOL.md: the requested centre lands on pixel ((size - 1)/2, (size - 1)/2).
  const Eigen::Vector4d centre = m * Eigen::Vector4d(63.5, 63.5, 0.0, 1.0);
  EXPECT_LT((centre.head<3>() - lps).norm(), 1e-9);
  EXPECT_NEAR(m.col(0).head<3>().norm(), 0.5, 1e-12);  // pixel_mm along u

  // A second tab joining now gets the same targets at once.
  Browser tab3(gateway.port());
  tab3.waitState([&](const json& s) { return s.contains("targets") && s["targets"].contains(id); });
  EXPECT_EQ(tab3.state()["targets"][id]["lps"], tab2.state()["targets"][id]["lps"]);

  // An emergency stop from a tab reaches the server.
  const json stop = tab3.request({{"op", "emergency_stop"}});
  EXPECT_EQ(stop["accepted"], true) << stop;
  tab2.waitState([](const json& s) { return e2e::phaseIs(s, "emergency"); });
}

TEST(Gateway, ServesTheAppAndNothingElse) {
  e2e::ServerProcess server(111);
  RunningGateway gateway(111);
  const auto index = httpGet(gateway.port(), "/");
  EXPECT_EQ(index.result(), http::status::ok);
  EXPECT_EQ(index[http::field::content_type], "text/html; charset=utf-8");
  EXPECT_NE(index.body().find("fixture page"), std::string::npos);
  EXPECT_EQ(httpGet(gateway.port(), "/missing.js").result(), http::status::not_found);
  EXPECT_EQ(httpGet(gateway.port(), "/../CMakeLists.txt").result(), http::status::bad_request);
  EXPECT_EQ(httpGet(gateway.port(), "/%2e%2e/CMakeLists.txt").result(), http::status::bad_request);
  EXPECT_EQ(httpGet(gateway.port(), "/.hidden").result(), http::status::bad_request);

  // /healthz reports the server once discovery has matched it.
  json health;
  for (int i = 0; i < 100; ++i) {
    health = json::parse(httpGet(gateway.port(), "/healthz").body());
    if (health["server"] == true) break;
    std::this_thread::sleep_for(50ms);
  }
  EXPECT_EQ(health["server"], true) << health;

  // A page from another origin may not open the WebSocket; the same origin may.
  EXPECT_THROW(Browser(gateway.port(), "http://evil.example"), beast::system_error);
  Browser same(gateway.port(), "http://127.0.0.1:" + std::to_string(gateway.port()));
  EXPECT_EQ(same.next()["type"], "hello");
}

// A tab that floods the gateway is told "busy" beyond 64 waiting requests; its emergency stop is
// never refused for that and goes ahead of everything queued.
TEST(Gateway, FloodIsBoundedAndEmergencyStopGoesFirst) {
  e2e::ServerProcess server(113);
  RunningGateway gateway(113);
  Browser tab(gateway.port());
  waitForServer(tab, tab.next());
  tab.waitState([](const json& s) { return s.contains("workflow"); });
  ASSERT_EQ(tab.request(command("load_volume", {{"path", "phantom:"}}))["accepted"], true);
  tab.waitState([](const json& s) {
    return s.contains("volume") && s["volume"]["status"] == "loaded" &&
           s["workflow"]["phase"] == "registration";
  });
  // 200 large slices at once (each takes the server milliseconds), then an emergency stop.
  constexpr int kSlices = 200;
  for (int i = 1; i <= kSlices; ++i) {
    tab.sendText(json{
        {"op", "slice"},
        {"seq", 1000 + i},
        {"view", "axial"},
        {"centre_lps", {0, 0, 0}},
        {"size_px", 512},
        {"overlays",
         "none"}}.dump());
  }
  tab.sendText(json{{"op", "emergency_stop"}, {"seq", 5000}}.dump());
  int busy = 0, slices = 0, slices_after_stop = 0;
  bool stopped = false;
  while (slices + busy < kSlices || !stopped) {
    const json m = tab.next(60s);
    if (m["type"] == "error" && m["code"] == "busy") ++busy;
    if (m["type"] == "slice") {
      ++slices;
      if (stopped) ++slices_after_stop;
    }
    if (m["type"] == "reply" && m["seq"] == 5000) {
      EXPECT_EQ(m["accepted"], true) << m;
      stopped = true;
    }
  }
  // The first 64 were queued, the rest refused at once (a few more may fit when a slice finishes
  // while the burst is still being read).
  EXPECT_GE(slices, 64);
  EXPECT_GE(busy, kSlices - 70);
  EXPECT_EQ(slices + busy, kSlices);
  // The stop overtook every queued slice but the one being rendered when it arrived (at most
  // a few: the DDS thread may have taken some before the stop was read off the socket).
  EXPECT_GE(slices_after_stop, 55);
}

// With DDS Security, a gateway holding the viewer identity tells its browsers what that role may
// not publish, and a command above it is refused by the permissions, not sent.
TEST(Gateway, AViewerGatewayKnowsWhatItMayNotDo) {
  const fs::path pki = fs::temp_directory_path() / ("ignav_web_pki_" + std::to_string(::getpid()));
  fs::remove_all(pki);
  const std::string make =
      IGNAV_SOURCE_DIR "/configs/security/make-test-pki.sh " + pki.string() + " >/dev/null";
  ASSERT_EQ(std::system(make.c_str()), 0);
  e2e::ServerProcess server(114, {"--identity", (pki / "service").string()});
  RunningGateway gateway(114, "web-viewer",
                         protocol::identityFromFolder((pki / "viewer").string()));
  Browser tab(gateway.port());
  const json hello = tab.next();
  EXPECT_EQ(hello["security"], true);
  EXPECT_EQ(hello["subject"], "CN=viewer,O=ignav,C=NL");
  const auto permitted = hello["permitted"].get<std::vector<std::string>>();
  auto has = [&](const char* c) {
    return std::find(permitted.begin(), permitted.end(), c) != permitted.end();
  };
  EXPECT_TRUE(has("query"));
  EXPECT_FALSE(has("add_target"));
  EXPECT_FALSE(has("approve"));
  waitForServer(tab, hello);
  tab.waitState([](const json& s) { return s.contains("workflow"); });
  const json refused = tab.request(command("load_volume", {{"path", "phantom:"}}));
  EXPECT_EQ(refused["type"], "error");
  EXPECT_EQ(refused["code"], "not_permitted") << refused;
  EXPECT_EQ(tab.request(command("query"))["accepted"], true);
  fs::remove_all(pki);
}

// A killed server stays matched on DDS until its lease runs out (10 s by default): the gateway
// goes by its Health samples (once a second) and says it is gone after 3 s without one, refuses
// requests meanwhile instead of letting them time out, and says it is back once it is.
TEST(Gateway, AKilledServerIsGoneWithinSecondsAndBackWhenRestarted) {
  e2e::ServerProcess server(115);
  RunningGateway gateway(115);
  Browser tab(gateway.port());
  const json hello = tab.next();
  waitForServer(tab, hello);
  tab.waitState([](const json& s) { return s.contains("health"); });
  EXPECT_EQ(json::parse(httpGet(gateway.port(), "/healthz").body())["server"], true);
  server.crash();
  const auto killed = std::chrono::steady_clock::now();
  for (json m = tab.next(); !(m["type"] == "connection" && m["server"] == false); m = tab.next()) {
  }
  const auto silence = std::chrono::steady_clock::now() - killed;
  // At most 3 s after the last sample, which came at most about 1 s before the kill.
  EXPECT_LT(silence, 4500ms);
  EXPECT_EQ(json::parse(httpGet(gateway.port(), "/healthz").body())["server"], false);
  const auto asked = std::chrono::steady_clock::now();
  const json refused = tab.request(command("query"));
  EXPECT_EQ(refused["code"], "no_server") << refused;
  // Refused at once, not after the reply timeout: bounded by that timeout, not by this machine.
  EXPECT_LT(std::chrono::steady_clock::now() - asked, GatewayOptions{}.reply_timeout / 2);
  EXPECT_NE(refused["message"].get<std::string>().find("domain 115"), std::string::npos);
  server.start();
  for (json m = tab.next(); !(m["type"] == "connection" && m["server"] == true); m = tab.next()) {
  }
  EXPECT_EQ(tab.request(command("query"))["accepted"], true);
}

TEST(Gateway, WithoutAServerRequestsFailClearlyAndTheStateSaysSo) {
  RunningGateway gateway(112);  // nothing on domain 112
  Browser tab(gateway.port());
  EXPECT_EQ(tab.next()["type"], "hello");
  const json r = tab.request(command("query"));
  EXPECT_EQ(r["type"], "error");
  EXPECT_EQ(r["code"], "no_server");
  EXPECT_NE(r["message"].get<std::string>().find("domain 112"), std::string::npos);
}

}  // namespace
}  // namespace ignav::web
