// Round trips through the web viewer's gateway, as a browser tab makes them (tools/bench/
// bench_web.sh starts ignav-server and ignav-web):
//   query  : command -> reply
//   click  : move_target -> reply
//   state  : move_target -> the state message with the moved target
//   slice  : a 512 x 512 axial slice with the feasible region -> the slice message (PNG in base64)
//   bare   : the same without overlays
//   e-stop : emergency stop -> reply
// Prints median and p99 in microseconds, and the slice message's size. The same round trips
// without the gateway: bench_latency.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include <Eigen/LU>

#include "browser_socket.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

void report(const char* what, std::vector<double> us) {
  std::sort(us.begin(), us.end());
  std::printf("%-7s median %8.0f us   p99 %8.0f us   (%zu rounds)\n", what, us[us.size() / 2],
              us[std::min(us.size() - 1, us.size() * 99 / 100)], us.size());
}

double sinceUs(Clock::time_point t) {
  return std::chrono::duration<double, std::micro>(Clock::now() - t).count();
}

json command(const std::string& kind, json extra = json::object()) {
  extra["op"] = "command";
  extra["kind"] = kind;
  return extra;
}

json point(const Eigen::Vector3d& p) {
  return json::array({p.x(), p.y(), p.z()});
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_web PORT [ROUNDS]\n");
    return 2;
  }
  const auto port = static_cast<std::uint16_t>(std::stoul(argv[1]));
  const int rounds = argc > 2 ? std::stoi(argv[2]) : 500;
  ignav::web::BrowserSocket tab(port);
  tab.waitState([](const json& s) { return s.contains("workflow"); });
  if (tab.request(command("load_volume", {{"path", "phantom:"}}))["accepted"] != true) return 3;
  tab.waitState([](const json& s) {
    return s.contains("volume") && s["volume"]["status"] == "loaded" &&
           s["workflow"]["phase"] == "registration";
  });
  if (tab.request(command("auto_fiducials"))["accepted"] != true) return 3;
  tab.waitState([](const json& s) {
    return s.contains("registration") && s["registration"]["status"] == "registered";
  });
  Eigen::Matrix4d image_to_robot;
  for (int i = 0; i < 16; ++i)
    image_to_robot(i / 4, i % 4) = tab.state()["registration"]["image_to_robot"][i];
  const Eigen::Matrix4d robot_to_image = image_to_robot.inverse();
  auto lps = [&](double x, double y, double z) {
    return (robot_to_image * Eigen::Vector4d(x, y, z, 1.0)).head<3>().eval();
  };
  const json added = tab.request(command("add_target", {{"points", {point(lps(8, 12, -175))}}}));
  const std::uint32_t id = added["target_id"];
  const std::string key = std::to_string(id);

  std::vector<double> query, click, state, slice, estop;
  for (int i = 0; i < rounds; ++i) {
    auto t = Clock::now();
    tab.request(command("query"));
    query.push_back(sinceUs(t));

    // Alternate between two reachable points so that every click changes the target.
    const Eigen::Vector3d p = lps(8.0 + (i % 2), 12.0, -175.0);
    t = Clock::now();
    tab.request(command("move_target", {{"ids", {id}}, {"points", {point(p)}}}));
    click.push_back(sinceUs(t));
    tab.waitState([&](const json& s) {
      const json& l = s["targets"][key]["lps"];
      return std::abs(l[0].get<double>() - p.x()) < 1e-9 &&
             std::abs(l[1].get<double>() - p.y()) < 1e-9 &&
             std::abs(l[2].get<double>() - p.z()) < 1e-9;
    });
    state.push_back(sinceUs(t));
  }
  // Slices with the feasible region drawn by the server (what the viewer asks for), and bare.
  std::size_t slice_bytes = 0;
  auto slices = [&](const char* overlays, std::vector<double>& out) {
    for (int i = 0; i < std::max(20, rounds / 10); ++i) {
      const auto t = Clock::now();
      const json s = tab.request({{"op", "slice"},
                                  {"view", "axial"},
                                  {"centre_lps", point(lps(0, 0, -170.0 - i % 10))},
                                  {"size_px", 512},
                                  {"pixel_mm", 0.3},
                                  {"overlays", overlays}});
      out.push_back(sinceUs(t));
      slice_bytes = std::max(slice_bytes, tab.lastMessageBytes());
      if (s["ok"] != true) return false;
    }
    return true;
  };
  std::vector<double> bare;
  if (!slices("region", slice) || !slices("none", bare)) return 4;
  for (int i = 0; i < std::max(20, rounds / 10); ++i) {
    const auto t = Clock::now();
    tab.request({{"op", "emergency_stop"}});
    estop.push_back(sinceUs(t));
    tab.request(command("reset_emergency"));
  }
  report("query", query);
  report("click", click);
  report("state", state);
  report("slice", slice);
  report("bare", bare);
  report("e-stop", estop);
  std::printf("slice message: %zu bytes (512 x 512 PNG in base64, with its mapping)\n",
              slice_bytes);
  return 0;
}
