// The patient's structures through a real server over DDS (issue 41): the built-in phantom's
// anatomy loaded with ignavctl, a clicked target whose needle crosses the urethra refused by name
// in TargetState and by lock_plan, an operator's override with a reason that the approval
// request shows, a segmentation that is no segmentation refused with the structures before kept,
// the anatomy written for 3D Slicer, the robot placed on the planning CT and the mounted robot
// measured against that, and the session replayed offline from its journal.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
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

// The reports thread writes the Slicer files a moment after the state says why: up to 5 s.
bool waitForFile(const std::filesystem::path& path) {
  for (int i = 0; i < 100 && !std::filesystem::exists(path); ++i)
    std::this_thread::sleep_for(50ms);
  return std::filesystem::exists(path);
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
  // And as an RT Structure Set in the phantom series' frame of reference: loaded over DDS, the
  // same structures, voxel for voxel as many, with their roles (PTV, AVOIDANCE, ORGAN; the site's
  // margins).
  ASSERT_TRUE(op->send("unlock_plan").accepted);
  auto voxels = [](const json& s) {
    std::map<std::string, std::pair<std::uint64_t, std::string>> out;
    for (const auto& one : s["structures"]["structures"])
      out[one["name"]] = {one["voxels"].get<std::uint64_t>(), one["role"].get<std::string>()};
    return out;
  };
  const auto from_phantom = voxels(op->state());
  const std::string rtstruct = (server.sessionDir() / "phantom_anatomy_rtstruct.dcm").string();
  const auto dicom = ctl("structures load " + rtstruct);
  ASSERT_EQ(dicom.exit_code, 0) << dicom.output;
  op->waitFor([&](const json& s) { return stateText(s, "structures", "source") == rtstruct; }, 10s);
  EXPECT_EQ(voxels(op->state()), from_phantom);
  EXPECT_EQ(stateText(op->state(), "structures", "message").find("not checked"), std::string::npos)
      << "the phantom's series carries a frame of reference";
  // A role given by command (ignavctl's words joined into NAME ROLE MM), and the structures as the
  // plan uses them exported for Slicer with it (the reports thread writes them after the step).
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

// The rest of a proposal's accept: `count` targets, every one planned; the plan locks, and the
// session, stopped, replays.
void acceptedLockedAndReplayed(ServerProcess& server, std::unique_ptr<protocol::Client> op,
                               std::size_t count) {
  op->waitFor([&](const json& s) { return s.contains("targets") && s["targets"].size() == count; },
              10s);
  for (const auto& [id, t] : op->state()["targets"].items())
    EXPECT_EQ(t["status"], "planned") << id << ": " << t.dump();
  lockAndWaitForApproval(*op);
  op.reset();
  const auto dir = server.sessionDir();
  server.stop();
  const auto [status, text] = replayVerified(dir);
  EXPECT_EQ(status, 0) << text;
}

// Targets that fill the phantom's prostate, proposed and accepted through ignavctl over DDS:
// the proposal lists them and is exported for Slicer; accepted (two by id, then the rest) they
// are planned targets that lock as one insertion; the session replays.
TEST(AnatomyE2E, TargetsProposedToFillTheProstateAreAcceptedAndLockAsOneInsertion) {
  constexpr std::uint32_t kProposalDomain = 191;
  ServerProcess server(kProposalDomain);
  auto op = server.client("operator");
  op->waitFor([](const json& s) { return s.contains("robot"); }, 10s);
  auto run = [](const std::string& args) { return ignavctlOn(kProposalDomain, args); };
  registeredPhantom(*op);
  ASSERT_EQ(run("structures load phantom").exit_code, 0);
  const auto refused = run("targets propose prostate 0.2");
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.output.find("bad_spacing"), std::string::npos) << refused.output;
  const auto proposed = run("targets propose prostate 8");
  ASSERT_EQ(proposed.exit_code, 0) << proposed.output;
  EXPECT_NE(proposed.output.find("targets proposed:"), std::string::npos) << proposed.output;
  EXPECT_NE(proposed.output.find("P1 "), std::string::npos) << proposed.output;
  op->waitFor(
      [](const json& s) { return stateText(s, "structures", "proposal_status") == "proposed"; },
      10s);
  const std::size_t count = op->state()["structures"]["proposed"].size();
  ASSERT_GT(count, 10u);
  // For Slicer: one control point per proposal, where the state says.
  const auto markups = server.sessionDir() / "proposed_targets.mrk.json";
  ASSERT_TRUE(waitForFile(markups));
  std::ifstream in(markups);
  const json slicer = json::parse(in);
  ASSERT_EQ(slicer["markups"][0]["controlPoints"].size(), count);
  const json first = op->state()["structures"]["proposed"][0];
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(slicer["markups"][0]["controlPoints"][0]["position"][a].get<double>(),
                first["lps"][a].get<double>(), 1e-3);
  }

  ASSERT_EQ(run("targets accept 2 1").exit_code, 0);
  op->waitFor([](const json& s) { return s.contains("targets") && s["targets"].size() == 2u; },
              10s);
  const auto again = run("targets accept 1");
  EXPECT_NE(again.output.find("unknown_proposal"), std::string::npos) << again.output;
  ASSERT_EQ(run("targets accept").exit_code, 0);
  acceptedLockedAndReplayed(server, std::move(op), count);
}

// A seed plan (issue 42) through ignavctl over DDS: bad requests refused by name with the session
// unchanged, then the site's default plan for the prostate, proposed as targets whose count and
// dose the state's message gives; accepted, they are planned targets that lock as one insertion,
// and the session replays.
TEST(AnatomyE2E, ASeedPlanForTheProstateIsProposedAcceptedAndLocked) {
  constexpr std::uint32_t kSeedDomain = 199;
  ServerProcess server(kSeedDomain);
  auto op = server.client("operator");
  op->waitFor([](const json& s) { return s.contains("robot"); }, 10s);
  auto run = [](const std::string& args) { return ignavctlOn(kSeedDomain, args); };
  registeredPhantom(*op);
  ASSERT_EQ(run("structures load phantom").exit_code, 0);
  const auto revision = op->state()["workflow"]["revision"].get<std::uint64_t>();
  for (const auto& [words, code] : std::vector<std::pair<std::string, std::string>>{
           {"prostate model=iridium_192", "unknown_seed_model"},
           {"prostate rx=0", "bad_seed_plan"},
           {"prostate strength=12", "bad_seed_plan"},
           {"bladder", "unknown_structure"}}) {
    const auto refused = run("targets seeds " + words);
    EXPECT_NE(refused.exit_code, 0) << words;
    EXPECT_NE(refused.output.find(code), std::string::npos) << refused.output;
  }
  EXPECT_EQ(op->state()["workflow"]["revision"].get<std::uint64_t>(), revision);
  const auto planned = run("targets seeds prostate");
  ASSERT_EQ(planned.exit_code, 0) << planned.output;
  EXPECT_NE(planned.output.find("seed plan: "), std::string::npos) << planned.output;
  op->waitFor(
      [](const json& s) { return stateText(s, "structures", "proposal_status") == "proposed"; },
      10s);
  const std::string message = stateText(op->state(), "structures", "proposal_message");
  const std::size_t count = op->state()["structures"]["proposed"].size();
  EXPECT_NE(
      message.find(fmt::format("seed plan: {} seeds of oncura_6711 at 0.6 U for 145 Gy", count)),
      std::string::npos)
      << message;
  ASSERT_GT(count, 20u);
  ASSERT_LE(count, 100u);
  ASSERT_EQ(run("targets accept").exit_code, 0);
  // Accepted, the seeds' dose: computed on the server, in the state, its files in the session
  // folder, its isodose lines on the slices.
  op->waitFor(
      [](const json& s) {
        const auto status = stateText(s, "structures", "dose_status");
        return status == "computed" || status == "failed";
      },
      120s);
  ASSERT_EQ(stateText(op->state(), "structures", "dose_status"), "computed")
      << stateText(op->state(), "structures", "dose_message");
  bool prostate_seen = false;
  for (const auto& d : op->state()["structures"]["dose"]) {
    if (d["structure"] != "prostate") continue;
    prostate_seen = true;
    EXPECT_EQ(d["which"], "planned");
    EXPECT_GE(d["v100"].get<double>(), 0.95 - 0.003);
    EXPECT_GE(d["d90_percent"].get<double>(), 99.7);
  }
  EXPECT_TRUE(prostate_seen) << op->state()["structures"].dump();
  for (const char* file :
       {"dose/planned_rtdose.dcm", "dose/planned_rtplan.dcm", "dose/structures_rtstruct.dcm",
        "dose/planned_dose.nrrd", "dose/dvh.png", "dose/dvh.csv"})
    EXPECT_TRUE(waitForFile(server.sessionDir() / file)) << file;
  protocol::SliceArgs through;
  through.view = "axial";
  const json first_target = op->state()["targets"].begin().value();
  through.centre_lps = vec(first_target["lps"]);
  through.size_px = 256;
  through.pixel_mm = 0.25;
  const auto slice = op->slice(through, 30s);
  ASSERT_TRUE(slice.ok) << slice.message;
  const cv::Mat img = cv::imdecode(slice.png, cv::IMREAD_COLOR);
  int isodose_px = 0;  // the 100 % line's red (255, 40, 40)
  for (int v = 0; v < img.rows; ++v)
    for (int u = 0; u < img.cols; ++u)
      isodose_px += img.at<cv::Vec3b>(v, u) == cv::Vec3b(40, 40, 255);
  EXPECT_GT(isodose_px, 40);
  const auto refused_dose = run("targets dose prostate rx=-5");
  EXPECT_NE(refused_dose.exit_code, 0);
  EXPECT_NE(refused_dose.output.find("bad_seed_plan"), std::string::npos) << refused_dose.output;
  acceptedLockedAndReplayed(server, std::move(op), count);
}

TEST(AnatomyE2E, TheRobotIsPlacedOnThePlanningCtAndTheMountedRobotMeasuredAgainstIt) {
  constexpr std::uint32_t kPlacementDomain = 192;
  ServerProcess server(kPlacementDomain);
  auto op = server.client("operator");
  op->waitFor([](const json& s) { return s.contains("robot"); }, 10s);
  auto run = [](const std::string& args) { return ignavctlOn(kPlacementDomain, args); };
  // The planning CT before the robot is registered: the CT and the structures only.
  ASSERT_TRUE(op->send("load_volume", {"phantom:", {}, {}}).accepted);
  op->waitFor([](const json& s) { return stateText(s, "volume", "status") == "loaded"; }, 60s);
  ASSERT_EQ(run("structures load phantom").exit_code, 0);
  const auto refused = run("structures place prostate from above");
  EXPECT_NE(refused.output.find("bad_approach"), std::string::npos) << refused.output;
  const auto placed = run("structures place prostate from superior");
  ASSERT_EQ(placed.exit_code, 0) << placed.output;
  EXPECT_NE(placed.output.find("robot placement placed"), std::string::npos) << placed.output;
  EXPECT_NE(placed.output.find("alternative 1"), std::string::npos) << placed.output;
  op->waitFor(
      [](const json& s) { return stateText(s, "structures", "placement_status") == "placed"; },
      10s);
  const json best = op->state()["structures"]["placements"][0];
  EXPECT_GT(best["coverage"].get<double>(), 0.6);
  EXPECT_TRUE(best["skin_seen"].get<bool>());
  EXPECT_LE(best["tilt_deg"].get<double>(), 20.0 + 1e-9);

  // For Slicer: the pose as an ITK transform (image -> robot: the origin to 0, the axis to -Z).
  const auto tfm = server.sessionDir() / "robot_placement.tfm";
  ASSERT_TRUE(waitForFile(tfm));
  std::ifstream in(tfm);
  std::string line, parameters;
  while (std::getline(in, line))
    if (line.rfind("Parameters:", 0) == 0) parameters = line.substr(11);
  std::istringstream numbers(parameters);
  Eigen::Matrix3d m;
  Eigen::Vector3d t;
  for (int k = 0; k < 9; ++k)
    numbers >> m(k / 3, k % 3);
  numbers >> t.x() >> t.y() >> t.z();
  ASSERT_TRUE(numbers) << parameters;
  Eigen::Vector3d origin, axis;
  for (int a = 0; a < 3; ++a) {
    origin[a] = best["origin_lps"][a].get<double>();
    axis[a] = best["axis_lps"][a].get<double>();
  }
  EXPECT_LT((m * origin + t).norm(), 1e-3);
  EXPECT_LT((m * axis - Eigen::Vector3d(0, 0, -1)).norm(), 1e-6);
  EXPECT_TRUE(waitForFile(server.sessionDir() / "feasible_volume.ply"));

  // Mounted (the phantom's robot, placed without this plan) and registered: measured against it.
  ASSERT_TRUE(op->send("auto_fiducials").accepted);
  op->waitFor(
      [](const json& s) { return stateText(s, "structures", "mounted_status") == "measured"; },
      30s);
  const json st = op->state()["structures"];
  ASSERT_EQ(st["mounted_status"], "measured") << st.dump();
  EXPECT_LT(st["mounted_coverage"].get<double>(), best["coverage"].get<double>());
  EXPECT_GT(st["mounted_axis_deg"].get<double>(), 1.0);
  EXPECT_NE(st["mounted_message"].get<std::string>().find("points less"), std::string::npos);

  op.reset();
  const auto dir = server.sessionDir();
  server.stop();
  const auto [status, text] = replayVerified(dir);
  EXPECT_EQ(status, 0) << text;
  std::ifstream report(dir / "report.md");
  const std::string md((std::istreambuf_iterator<char>(report)), {});
  EXPECT_NE(md.find("## Robot placement ('prostate' from superior)"), std::string::npos);
}

}  // namespace
}  // namespace ignav::e2e
