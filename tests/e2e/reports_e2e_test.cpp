// The report and the Slicer exports are written on the server's reports thread (issue 22.2): while
// the report slices of a lock are rendered, commands are still answered at once. Real ignav-server
// processes over Cyclone DDS on loopback; domains 120-121.
//
// The CT is deliberately large: the built-in robot phantom at 0.4 mm isotropic (256 x 256 x 350
// voxels, 46 MB), written here as NRRD. A lock with 12 targets renders 24 slices with the feasible
// region tinted in; the server that rendered them on its event thread answered no query for that
// whole time (seconds here).
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/image_io.hpp"
#include "ignav/volume/phantom.hpp"
#include "server_process.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using protocol::Client;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

// A correctness bound, not a goal (ARCHITECTURE.md: 50 ms): the worst query against the rendering
// it ran beside, both measured here, so that neither this machine's load nor the build sets it
// (the server that rendered on its event thread: 829 ms for 847 ms). Under AddressSanitizer, with
// other sanitized suites on both cores, the server's own work is several times slower.
constexpr double kShareOfRendering = kSanitized ? 0.5 : 1.0 / 3.0;

const config::Robot& paperRobot() {
  static const config::Robot robot =
      config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml").value();
  return robot;
}

std::string slurp(const std::filesystem::path& path) {
  std::stringstream s;
  s << std::ifstream(path).rdbuf();
  return s.str();
}

// The built-in robot phantom (as the server makes it: oblique, 8 HU noise) at `spacing_mm`
// isotropic over the same extent, as NRRD in `folder`.
std::string writePhantomNrrd(const std::filesystem::path& folder, double spacing_mm) {
  const auto& robot = paperRobot();
  auto rp = registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan);
  EXPECT_TRUE(rp.ok());
  auto spec = rp->spec;
  for (int a = 0; a < 3; ++a) {
    spec.dims[static_cast<std::size_t>(a)] = static_cast<int>(
        std::lround(spec.dims[static_cast<std::size_t>(a)] * spec.spacing_mm[a] / spacing_mm));
  }
  spec.spacing_mm = Eigen::Vector3d::Constant(spacing_mm);
  spec.oblique = true;
  spec.noise_sigma_hu = 8.0;
  auto v = volume::makePhantom(spec);
  EXPECT_TRUE(v.ok());
  std::filesystem::create_directories(folder);
  const std::string path = (folder / "large_phantom.nrrd").string();
  EXPECT_TRUE(volume::writeNrrd(*v, path, volume::NrrdEncoding::kRaw).ok());
  return path;
}

// Twelve reachable targets around the robot's axis (robot frame), added by clicks in the image.
std::vector<std::uint32_t> addTwelveTargets(Client& c) {
  std::vector<std::uint32_t> ids;
  for (int i = 0; i < 12; ++i) {
    const double angle = (i % 6) * 30.0 * M_PI / 180.0;
    const double radius = i < 6 ? 12.0 : 17.0;
    const Eigen::Vector3d robot_mm(radius * std::cos(angle), radius * std::sin(angle),
                                   -172.0 - 2.0 * i);
    const auto r = c.send("add_target", {"", {lpsOf(c.state(), robot_mm)}, {}});
    EXPECT_TRUE(r.accepted) << r.message;
    ids.push_back(r.target_id);
  }
  c.waitFor([&](const json& s) { return s["targets"].size() == ids.size(); }, 5s);
  for (const auto id : ids) {
    const json& t = c.state()["targets"][std::to_string(id)];
    EXPECT_TRUE(t["reachable"].get<bool>()) << t.dump();
  }
  return ids;
}

// The report lists the coronal and axial slices of every target.
bool listsEverySlice(const std::string& report, const std::vector<std::uint32_t>& ids) {
  for (const auto id : ids) {
    for (const char* view : {"coronal", "axial"}) {
      if (report.find("report/T" + std::to_string(id) + "_" + view + ".png") == std::string::npos) {
        return false;
      }
    }
  }
  return true;
}

// "report slices written in N ms" from the server's log (-1 until it is there).
double renderingMsFromLog(const ServerProcess& server) {
  static const std::regex line(R"(report slices written in (\d+) ms)");
  const std::string log = server.serverLog();
  double last = -1.0;
  for (auto it = std::sregex_iterator(log.begin(), log.end(), line); it != std::sregex_iterator();
       ++it) {
    last = std::stod((*it)[1].str());
  }
  return last;
}

TEST(ReportsE2E, QueriesAreAnsweredAtOnceWhileALockRendersTheReportSlicesOfALargeCt) {
  const auto folder =
      std::filesystem::temp_directory_path() / ("ignav_e2e_large_ct_" + std::to_string(::getpid()));
  const std::string nrrd = writePhantomNrrd(folder, 0.4);
  ServerProcess server(120);
  auto op = server.client("operator");
  auto t = Clock::now();
  ASSERT_TRUE(op->send("load_volume", {nrrd, {}, {}}).accepted);
  op->waitFor([](const json& s) { return stateText(s, "volume", "status") == "loaded"; }, 60s);
  std::filesystem::remove_all(folder);
  ASSERT_EQ(stateText(op->state(), "volume", "status"), "loaded") << op->state()["volume"].dump();
  const double load_ms = msOf(Clock::now() - t);
  // The detection runs on the server's detector thread: timed until the registration shows.
  t = Clock::now();
  const auto detected = op->send("auto_fiducials", {}, 60s);
  ASSERT_TRUE(detected.accepted) << detected.message;
  op->waitFor([](const json& s) { return stateText(s, "registration", "status") == "registered"; },
              60s);
  const double detect_ms = msOf(Clock::now() - t);
  const auto ids = addTwelveTargets(*op);

  QueryWatcher queries(server.client("watcher"), 20ms);
  std::this_thread::sleep_for(200ms);
  t = Clock::now();
  const auto locked = op->send("lock_plan", {}, 60s);
  const double lock_reply_ms = msOf(Clock::now() - t);
  ASSERT_TRUE(locked.accepted) << locked.message;
  // The report that lists every slice, written after them.
  std::string report;
  while (!listsEverySlice(report, ids) && Clock::now() - t < 60s) {
    std::this_thread::sleep_for(25ms);
    report = slurp(server.sessionDir() / "report.md");
  }
  const double written_ms = msOf(Clock::now() - t);
  std::this_thread::sleep_for(100ms);  // and a few queries after
  queries.stop();
  ASSERT_TRUE(listsEverySlice(report, ids)) << report;
  double rendering_ms = -1.0;
  for (int i = 0; i < 40 && rendering_ms < 0; ++i) {
    rendering_ms = renderingMsFromLog(server);
    if (rendering_ms < 0) std::this_thread::sleep_for(25ms);
  }
  std::cout << "large CT " << op->state()["volume"]["dims"].dump() << ": load " << load_ms
            << " ms, auto_fiducials " << detect_ms << " ms; lock_plan reply " << lock_reply_ms
            << " ms, report slices rendered in " << rendering_ms
            << " ms (report listing them after " << written_ms << " ms); worst query "
            << queries.worstMs() << " ms of " << queries.answered() << std::endl;
  ASSERT_GT(rendering_ms, 0.0) << server.serverLog();
  // The slices decode, at the size the report draws them.
  for (const char* view : {"coronal", "axial"}) {
    const auto png =
        server.sessionDir() / "report" / ("T" + std::to_string(ids.back()) + "_" + view + ".png");
    EXPECT_GT(std::filesystem::file_size(png), 1000u) << png;
  }
  std::ostringstream timeline;  // when each query was sent (ms from the lock) and how long it took
  for (const auto& q : queries.samples()) {
    timeline << " " << std::lround(msOf(q.sent - t)) << ":" << std::lround(q.ms);
  }
  std::cout << "queries (sent:took ms)" << timeline.str() << std::endl;
  EXPECT_GT(queries.answered(), 10);
  EXPECT_LT(queries.worstMs(), kShareOfRendering * rendering_ms)
      << "a query waited behind the report slices";
}

TEST(ReportsE2E, AServerStoppedRightAfterALockStillWritesEverySliceTheReportAndTheExports) {
  ServerProcess server(121);
  auto op = server.client("operator");
  ASSERT_TRUE(op->send("load_volume", {"phantom:", {}, {}}).accepted);
  op->waitFor([](const json& s) { return stateText(s, "volume", "status") == "loaded"; }, 60s);
  ASSERT_TRUE(op->send("auto_fiducials").accepted);
  op->waitFor([](const json& s) { return stateText(s, "registration", "status") == "registered"; },
              10s);
  const auto ids = addTwelveTargets(*op);
  ASSERT_TRUE(op->send("lock_plan").accepted);
  EXPECT_EQ(server.stop(), 0);  // at once: the reports thread finishes what it was handed
  const std::string report = slurp(server.sessionDir() / "report.md");
  EXPECT_TRUE(listsEverySlice(report, ids)) << report;
  for (const auto id : ids) {
    EXPECT_NE(report.find("| T" + std::to_string(id) + " |"), std::string::npos) << report;
    for (const char* view : {"coronal", "axial"}) {
      EXPECT_TRUE(std::filesystem::exists(server.sessionDir() / "report" /
                                          ("T" + std::to_string(id) + "_" + view + ".png")));
    }
  }
  EXPECT_FALSE(std::filesystem::exists(server.sessionDir() / "report.md.tmp"));
  const json targets = json::parse(slurp(server.sessionDir() / "targets.mrk.json"));
  EXPECT_EQ(targets["markups"][0]["controlPoints"].size(), ids.size()) << targets.dump();
  EXPECT_TRUE(std::filesystem::exists(server.sessionDir() / "fiducials.mrk.json"));
  EXPECT_TRUE(std::filesystem::exists(server.sessionDir() / "image_to_robot.tfm"));
}

}  // namespace
}  // namespace ignav::e2e
