// The patient's structures through a real server over DDS (issue 41): the built-in phantom's
// anatomy loaded with ignavctl, a clicked target whose needle crosses the urethra refused by name
// in TargetState and by lock_plan, an operator's override with a reason that the approval
// request shows, a segmentation that is no segmentation refused with the structures before kept,
// the anatomy written for 3D Slicer, and the session replayed offline from its journal.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <filesystem>
#include <optional>
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "ignav/anatomy/structures.hpp"
#include "server_process.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

constexpr std::uint32_t kDomain = 190;

CommandRun ctl(const std::string& args) {
  return ignavctlOn(kDomain, args);
}

TEST(AnatomyE2E, ATargetWhoseNeedleCrossesTheUrethraIsRefusedUntilOverriddenWithAReason) {
  ServerProcess server(kDomain);
  auto op = server.client("operator");
  op->waitFor([](const json& s) { return s.contains("robot"); }, 10s);
  const double r_max = op->state()["robot"]["r_max_mm"].get<double>();
  // The phantom's urethra runs parallel to the robot's axis at x = 0.55 r_max (robot frame).
  const std::uint32_t clear = plannedTarget(*op, {-0.85 * r_max, 0.0, -178.0});

  const auto loaded = ctl("structures load phantom");
  ASSERT_EQ(loaded.exit_code, 0) << loaded.output;
  EXPECT_NE(loaded.output.find("urethra"), std::string::npos) << loaded.output;
  EXPECT_NE(loaded.output.find("avoid"), std::string::npos) << loaded.output;
  op->waitFor([](const json& s) { return stateText(s, "structures", "status") == "loaded"; }, 10s);
  const json structures = op->state()["structures"];
  EXPECT_EQ(structures["site"], "prostate brachytherapy");
  ASSERT_EQ(structures["structures"].size(), 4u) << structures.dump();
  op->waitFor([&](const json& s) { return targetState(s, clear)["clearances"].size() == 3u; }, 10s);
  EXPECT_EQ(targetState(op->state(), clear)["status"], "planned");

  const auto added =
      op->send("add_target", {"", {lpsOf(op->state(), {0.85 * r_max, 0.0, -178.0})}, {}});
  ASSERT_TRUE(added.accepted) << added.message;
  const std::uint32_t crossing = added.target_id;
  EXPECT_NE(added.message.find("'urethra'"), std::string::npos) << added.message;
  op->waitFor([&](const json& s) { return s["targets"].contains(std::to_string(crossing)); }, 10s);
  const json& t = targetState(op->state(), crossing);
  EXPECT_EQ(t["status"], "too_close") << t.dump();
  ASSERT_FALSE(t["clearances"].empty());
  EXPECT_EQ(t["clearances"][0]["structure"], "urethra");
  EXPECT_TRUE(t["clearances"][0]["too_close"].get<bool>());
  EXPECT_LT(t["clearances"][0]["distance_mm"].get<double>(), 0.0);  // it enters the urethra
  // The structures' outlines on a slice through the target: the urethra's yellow (255, 230, 51).
  protocol::SliceArgs through;
  through.view = "axial";
  through.centre_lps = vec(t["lps"]);
  through.size_px = 256;
  through.pixel_mm = 0.25;
  const auto slice = op->slice(through, 30s);
  ASSERT_TRUE(slice.ok);
  const cv::Mat img = cv::imdecode(slice.png, cv::IMREAD_COLOR);
  int urethra_px = 0;
  for (int v = 0; v < img.rows; ++v)
    for (int u = 0; u < img.cols; ++u)
      urethra_px += img.at<cv::Vec3b>(v, u) == cv::Vec3b(51, 230, 255);
  EXPECT_GT(urethra_px, 40);  // its 3 mm circle's outline at 0.25 mm pixels: ~75
  const auto listed = ctl("targets ls");
  EXPECT_NE(listed.output.find("TOO CLOSE"), std::string::npos) << listed.output;

  const auto locked = op->send("lock_plan");
  EXPECT_EQ(locked.error_code, "too_close") << locked.message;
  EXPECT_NE(locked.message.find(fmt::format("target {}", crossing)), std::string::npos);

  // A file that is no segmentation: refused, the phantom's anatomy stays in use.
  const auto bad = ctl("structures load " IGNAV_SOURCE_DIR "/configs/server.yaml");
  EXPECT_NE(bad.exit_code, 0) << bad.output;
  EXPECT_NE(bad.output.find("not a segmentation"), std::string::npos) << bad.output;
  op->waitFor(
      [](const json& s) {
        return stateText(s, "structures", "message").find("was refused") != std::string::npos;
      },
      10s);
  EXPECT_EQ(op->state()["structures"]["structures"].size(), 4u);

  const auto overridden = ctl(fmt::format("targets override {} urethra stented, agreed", crossing));
  ASSERT_EQ(overridden.exit_code, 0) << overridden.output;
  op->waitFor([&](const json& s) { return targetState(s, crossing)["status"] == "planned"; }, 10s);
  EXPECT_EQ(targetState(op->state(), crossing)["clearance_override"], "urethra stented, agreed");
  ASSERT_TRUE(op->send("remove_target", {"", {}, {clear}}).accepted);
  lockAndWaitForApproval(*op);
  const std::string summary = stateText(op->state(), "approval", "summary");
  EXPECT_NE(summary.find("CLEARANCE OVERRIDDEN"), std::string::npos) << summary;
  EXPECT_NE(summary.find("urethra stented, agreed"), std::string::npos) << summary;

  // The anatomy, written for 3D Slicer beside the phantom's series, reads back.
  const auto written =
      anatomy::readSegNrrd((server.sessionDir() / "phantom_anatomy.seg.nrrd").string());
  ASSERT_TRUE(written.ok()) << written.error().message;
  EXPECT_EQ(written->structures.size(), 4u);
  // A role given by command (ignavctl's words joined into NAME ROLE MM), and the structures as the
  // plan uses them exported for Slicer with it (the reports thread writes them after the step).
  ASSERT_TRUE(op->send("unlock_plan").accepted);
  const auto role = ctl("structures role rectum avoid 6");
  ASSERT_EQ(role.exit_code, 0) << role.output;
  std::optional<anatomy::StructureSet> used;
  for (int i = 0; i < 200; ++i) {
    auto read = anatomy::readSegNrrd((server.sessionDir() / "structures.seg.nrrd").string());
    if (read.ok() && read->find("rectum")->margin_mm == 6.0) {
      used = std::move(read).value();
      break;
    }
    std::this_thread::sleep_for(50ms);
  }
  ASSERT_TRUE(used.has_value());
  EXPECT_EQ(used->find("urethra")->role, anatomy::Role::kAvoid);
  EXPECT_EQ(used->find("prostate")->role, anatomy::Role::kTarget);
  op.reset();
  const auto dir = server.sessionDir();
  server.stop();
  const auto [status, text] = replayVerified(dir);
  EXPECT_EQ(status, 0) << text;
}

}  // namespace
}  // namespace ignav::e2e
