// The closed loop's measuring half end to end (issue 23): a real server moves the simulated robot
// to three targets; a confirmation CT is made with a seed at each target, displaced by a known
// amount in the robot frame (the truth); `ignav-plan verify` on the recorded session and that CT
// must report those errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "ignav/compensation/compensation.hpp"
#include "ignav/config/tissue_profiles.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/phantom.hpp"
#include "server_process.hpp"
#include "support/phantom_ct.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

// `--figure` and `--report` wrote a PNG (as wide as three panels) and a Markdown report whose
// table shows each target's error as the JSON does, with the figure linked beside it.
void expectReportFiles(const std::filesystem::path& dir, const json& verified) {
  const cv::Mat figure = cv::imread((dir / "targeting.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(figure.empty()) << "no PNG at " << dir / "targeting.png";
  EXPECT_GT(figure.cols, 3 * figure.rows / 2);
  EXPECT_EQ(verified["figure"], (dir / "targeting.png").string());
  std::ifstream in(dir / "targeting.md");
  const std::string report((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_FALSE(report.empty()) << "no report at " << dir / "targeting.md";
  EXPECT_NE(report.find("](targeting.png)"), std::string::npos) << report;
  for (const auto& row : verified["targets"]) {
    const std::string id = "| " + std::to_string(row["id"].get<std::uint32_t>()) + " |";
    const auto at = report.find(id);
    ASSERT_NE(at, std::string::npos) << id << "\n" << report;
    const std::string line = report.substr(at, report.find('\n', at) - at);
    EXPECT_NE(line.find(fmt::format("| {:.2f} |", row["error_mm"].get<double>())),
              std::string::npos)
        << line;
  }
}

TEST(VerificationE2E, ErrorsMeasuredOnAConfirmationCtAreTheSeedsTrueDisplacements) {
  const std::filesystem::path ct_dir = std::filesystem::temp_directory_path() /
                                       ("ignav_e2e_confirmation_" + std::to_string(::getpid()));
  std::filesystem::remove_all(ct_dir);
  // Where each seed really is, relative to its target, in the robot frame (mm): lateral and
  // depth errors of the paper's size (Table V: 1-4 mm).
  const std::vector<Eigen::Vector3d> targets = {{8, 12, -175}, {-6, 10, -182}, {4, -9, -170}};
  const std::vector<Eigen::Vector3d> offsets = {
      {1.2, -0.8, -1.5}, {-2.0, 0.6, 0.9}, {0.4, 2.1, -0.7}};
  ServerProcess server(180, {"--controller-speed", "40000"});
  auto op = server.client("operator");
  const std::vector<std::uint32_t> ids = insertAll(*op, targets);
  const json state = op->state();
  op.reset();
  server.stop();  // the session folder stays until `server` goes (its name is the session id)
  const std::filesystem::path session = server.sessionDir();
  ASSERT_EQ(ids.size(), targets.size());

  // The confirmation scan: the same phantom (robot and markers where they were) with the seeds.
  const auto& robot = *test::paperRobot();
  auto rp = registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan);
  ASSERT_TRUE(rp) << rp.error().message;
  const Eigen::Matrix4d robot_to_image_true = rp->image_to_robot_true.inverse();
  std::map<std::uint32_t, Eigen::Vector3d> planned_robot;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const Eigen::Vector3d planned = vec(state["targets"][std::to_string(ids[i])]["robot"]);
    planned_robot[ids[i]] = planned;
    volume::PhantomSeed seed;
    seed.centre_lps_mm = (robot_to_image_true * (planned + offsets[i]).homogeneous()).head<3>();
    seed.axis_lps = robot_to_image_true.topLeftCorner<3, 3>() * Eigen::Vector3d::UnitZ();
    rp->spec.seeds.push_back(seed);
  }
  auto ct = volume::makePhantom(rp->spec);
  ASSERT_TRUE(ct) << ct.error().message;
  ASSERT_TRUE(volume::writeDicomSeries(*ct, ct_dir.string()));

  const std::string robot_yaml = IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml";
  const std::filesystem::path report_dir = ct_dir.string() + "_report";
  std::filesystem::create_directories(report_dir);
  const auto [status, out] =
      runPlan("verify " + session.string() + " " + ct_dir.string() + " --robot " + robot_yaml +
              " --json --figure " + (report_dir / "targeting.png").string() + " --report " +
              (report_dir / "targeting.md").string());
  ASSERT_EQ(status, 0) << out;
  const json v = json::parse(out);
  expectReportFiles(report_dir, v);
  std::filesystem::remove_all(report_dir);
  EXPECT_TRUE(v["registration"]["reused"].get<bool>()) << v["registration"].dump();
  EXPECT_LT(v["registration"]["marker_shift_mm"].get<double>(), 0.5);
  ASSERT_EQ(v["targets"].size(), targets.size()) << out;
  // What a perfect localiser reports, through the session's registration (which carries its own
  // small error): the seed's true LPS position in that registration's robot frame, less the plan.
  const Eigen::Matrix4d session_image_to_robot = imageToRobot(state);
  for (const auto& row : v["targets"]) {
    const auto id = row["id"].get<std::uint32_t>();
    const std::size_t i =
        static_cast<std::size_t>(std::find(ids.begin(), ids.end(), id) - ids.begin());
    ASSERT_LT(i, ids.size());
    const Eigen::Vector3d truth_lps =
        (robot_to_image_true * (planned_robot[id] + offsets[i]).homogeneous()).head<3>();
    const Eigen::Vector3d expected =
        (session_image_to_robot * truth_lps.homogeneous()).head<3>() - planned_robot[id];
    EXPECT_LT((vec(row["error_robot_mm"]) - expected).norm(), 0.1)
        << "target " << id << ": " << row.dump();
    EXPECT_NEAR(row["error_mm"].get<double>(), offsets[i].norm(), 0.15) << row.dump();
    // Depth is + when deeper than planned: deeper is -z in the robot frame.
    EXPECT_NEAR(row["depth_mm"].get<double>(), -expected.z(), 0.1) << row.dump();
  }
  EXPECT_EQ(v["summary"]["error"]["count"], targets.size());

  // The planning CT shows no seeds: a clear refusal, and nothing printed as a result.
  const auto [no_seed_status, no_seed_out] =
      runPlan("verify " + session.string() + " " + (session / "phantom_ct").string() + " --robot " +
                  robot_yaml + " --json",
              true);
  EXPECT_NE(no_seed_status, 0);
  EXPECT_NE(no_seed_out.find("no seeds found"), std::string::npos) << no_seed_out;

  std::filesystem::remove_all(ct_dir);
}

// The loop closed offline: the seeds land where a tissue the server was not told deflects the
// needle (agar, seed 000's Table I, in the extended bicycle model): `ignav-plan
// confirmation-phantom` makes that confirmation CT; verify measures the errors and fits the tissue
// from them; aiming with the fitted tissue lands closer on the same targets.
TEST(VerificationE2E, ATissueHiddenFromTheServerIsFittedFromTheErrorsAndCompensatesThem) {
  const std::filesystem::path ct_dir = std::filesystem::temp_directory_path() /
                                       ("ignav_e2e_hidden_tissue_" + std::to_string(::getpid()));
  std::filesystem::remove_all(ct_dir);
  const std::vector<Eigen::Vector3d> targets = {{8, 12, -175},  {-6, 10, -182}, {4, -9, -170},
                                                {10, -4, -186}, {-9, -7, -178}, {3, 14, -190}};
  ServerProcess server(181, {"--controller-speed", "40000"});
  auto op = server.client("operator");
  const std::vector<std::uint32_t> ids = insertAll(*op, targets);
  const json state = op->state();
  op.reset();
  server.stop();
  const std::filesystem::path session = server.sessionDir();

  // The physical world: the tool deposits each seed where agar deflects the needle.
  const std::string robot_yaml = IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml";
  const auto [made_status, made_out] =
      runPlan("confirmation-phantom " + session.string() + " --robot " + robot_yaml + " --out " +
              ct_dir.string() +
              " --hidden-tissue agar --tissues " IGNAV_SOURCE_DIR "/configs/tissues.yaml --json");
  ASSERT_EQ(made_status, 0) << made_out;
  const json truth = json::parse(made_out);
  EXPECT_EQ(truth["hidden_tissue"]["name"], "agar");
  EXPECT_EQ(truth["hidden_tissue"]["lambda1"], 0.49);
  EXPECT_EQ(truth["hidden_tissue"]["lambda2"], 0.22);
  json written = truth;  // the truth file, beside the series, holds all of it
  for (const char* key : {"out_dir", "files", "truth_path"})
    written.erase(key);
  const std::string truth_file = ct_dir.string() + "_truth.json";
  EXPECT_EQ(truth["truth_path"], truth_file);
  EXPECT_EQ(json::parse(std::ifstream(truth_file)), written);
  ASSERT_EQ(truth["targets"].size(), targets.size()) << made_out;
  // A second scan into the same folder would mix two series; a folder under a file cannot be.
  for (const auto& [out_dir, reason] :
       {std::pair<std::string, std::string>{ct_dir.string(), "the output folder is not empty"},
        {truth_file + "/ct", "cannot make the output folder"}}) {
    const auto [refused_status, refused_out] = runPlan(
        "confirmation-phantom " + session.string() + " --robot " + robot_yaml + " --out " + out_dir,
        true);
    EXPECT_NE(refused_status, 0) << refused_out;
    EXPECT_NE(refused_out.find(reason), std::string::npos) << refused_out;
  }

  // The tool's truth against the recipe done here by hand: each target's joints (from the state,
  // as the server moved there) landed in agar by the model, mapped by the phantom's true
  // robot -> image transform.
  const auto& robot = *test::paperRobot();
  auto profiles = config::loadTissueProfiles(IGNAV_SOURCE_DIR "/configs/tissues.yaml");
  ASSERT_TRUE(profiles) << profiles.error().message;
  compensation::DeflectionModel hidden;
  hidden.needle = profiles->needle;
  hidden.tissue = {0.49, 0.22};  // agar
  auto rp = registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan);
  ASSERT_TRUE(rp) << rp.error().message;
  const Eigen::Matrix4d robot_to_image_true = rp->image_to_robot_true.inverse();
  std::map<std::uint32_t, Eigen::Vector3d> planned, landed;
  for (const auto id : ids) {
    const json& t = state["targets"][std::to_string(id)];
    planned[id] = vec(t["robot"]);
    const kinematics::Joints joints{t["joints"][0].get<double>(), t["joints"][1].get<double>(),
                                    t["joints"][2].get<double>()};
    const auto landing = compensation::predictLanding(robot.kinematics, hidden, joints);
    ASSERT_TRUE(landing) << landing.error().message;
    landed[id] = landing->tip_mm;
  }
  for (const auto& row : truth["targets"]) {
    const auto id = row["id"].get<std::uint32_t>();
    ASSERT_EQ(landed.count(id), 1u) << row.dump();
    EXPECT_LT((vec(row["planned_robot_mm"]) - planned[id]).norm(), 1e-6) << row.dump();
    EXPECT_LT((vec(row["landing_robot_mm"]) - landed[id]).norm(), 1e-6) << row.dump();
    const Eigen::Vector3d lps = (robot_to_image_true * landed[id].homogeneous()).head<3>();
    EXPECT_LT((vec(row["landing_lps_mm"]) - lps).norm(), 1e-6) << row.dump();
  }

  const auto markups = ct_dir.string() + "_seeds.mrk.json";
  const auto [status, out] =
      runPlan("verify " + session.string() + " " + ct_dir.string() + " --robot " + robot_yaml +
              " --fit-tissue hidden_agar --markups " + markups + " --json");
  ASSERT_EQ(status, 0) << out;
  const json v = json::parse(out);
  const Eigen::Matrix4d session_image_to_robot = imageToRobot(state);
  double uncompensated_sum = 0.0;
  for (const auto& row : v["targets"]) {
    const auto id = row["id"].get<std::uint32_t>();
    const Eigen::Vector3d truth_lps = (robot_to_image_true * landed[id].homogeneous()).head<3>();
    const Eigen::Vector3d expected =
        (session_image_to_robot * truth_lps.homogeneous()).head<3>() - planned[id];
    EXPECT_LT((vec(row["error_robot_mm"]) - expected).norm(), 0.1) << row.dump();
    uncompensated_sum += (landed[id] - planned[id]).norm();
  }
  ASSERT_EQ(v["targets"].size(), targets.size());
  // The seeds in Slicer's markups format, one per target, in LPS.
  const json mrk = json::parse(std::ifstream(markups));
  EXPECT_EQ(mrk["markups"][0]["controlPoints"].size(), targets.size());
  EXPECT_EQ(mrk["markups"][0]["coordinateSystem"], "LPS");

  // The fit recovers the hidden tissue within its standard errors (twice, for a 95 % interval).
  const json& fit = v["tissue_fit"];
  const double se1 = fit["standard_errors"][0], se2 = fit["standard_errors"][1];
  EXPECT_LT(std::abs(fit["lambda1"].get<double>() - 0.49), 2.0 * se1 + 1e-9) << fit.dump();
  EXPECT_LT(std::abs(fit["lambda2"].get<double>() - 0.22), 2.0 * se2 + 1e-9) << fit.dump();
  EXPECT_LT(se2, 0.2) << fit.dump();
  EXPECT_NE(fit["profile_yaml"].get<std::string>().find("hidden_agar:"), std::string::npos);

  // Aimed with the fitted tissue, the same targets land (in the hidden tissue) far closer.
  compensation::DeflectionModel fitted = hidden;
  fitted.tissue = {fit["lambda1"].get<double>(), fit["lambda2"].get<double>()};
  double compensated_sum = 0.0;
  for (const auto id : ids) {
    const auto aimed = compensation::compensate(robot.kinematics, fitted, planned[id]);
    ASSERT_TRUE(aimed) << "target " << id << ": " << aimed.error().message;
    const auto landing = compensation::predictLanding(robot.kinematics, hidden, aimed->compensated);
    ASSERT_TRUE(landing) << landing.error().message;
    compensated_sum += (landing->tip_mm - planned[id]).norm();
  }
  std::cout << "hidden agar fitted: lambda1 " << fit["lambda1"] << " ± " << se1 << ", lambda2 "
            << fit["lambda2"] << " ± " << se2 << "; mean landing error uncompensated "
            << uncompensated_sum / static_cast<double>(ids.size()) << " mm, compensated "
            << compensated_sum / static_cast<double>(ids.size()) << " mm\n";
  EXPECT_GT(uncompensated_sum, 5.0 * compensated_sum)
      << "mean error uncompensated " << uncompensated_sum / static_cast<double>(ids.size())
      << " mm, compensated " << compensated_sum / static_cast<double>(ids.size()) << " mm";

  // The needle left in at the first target: it runs through the markers on its axis, so the scan
  // does not register on them (markers_missing); --same-frame registers it by the session's
  // registration. Its tip is measured where agar put it, and its path joins the fit.
  const std::filesystem::path needle_dir = ct_dir.string() + "_needle";
  std::filesystem::remove_all(needle_dir);
  const auto [needle_status, needle_out] = runPlan(
      "confirmation-phantom " + session.string() + " --robot " + robot_yaml + " --out " +
      needle_dir.string() +
      " --hidden-tissue agar --tissues " IGNAV_SOURCE_DIR "/configs/tissues.yaml --needle-at " +
      std::to_string(ids[0]));
  ASSERT_EQ(needle_status, 0) << needle_out;
  const std::string verify_needle =
      "verify " + session.string() + " " + needle_dir.string() + " --robot " + robot_yaml;
  const auto [merged_status, merged_out] = runPlan(verify_needle, true);
  EXPECT_NE(merged_status, 0) << merged_out;
  EXPECT_NE(merged_out.find("markers_missing"), std::string::npos) << merged_out;
  const auto [same_status, same_out] =
      runPlan(verify_needle + " --same-frame --fit-tissue hidden_agar --json");
  ASSERT_EQ(same_status, 0) << same_out;
  const json vn = json::parse(same_out);
  EXPECT_TRUE(vn["registration"]["by_matrix"].get<bool>());
  ASSERT_EQ(vn["targets"].size(), targets.size());
  for (const auto& row : vn["targets"]) {
    const auto id = row["id"].get<std::uint32_t>();
    EXPECT_EQ(row["matched"], id == ids[0] ? "tip" : "seed") << row.dump();
    const Eigen::Vector3d truth_lps = (robot_to_image_true * landed[id].homogeneous()).head<3>();
    const Eigen::Vector3d expected =
        (session_image_to_robot * truth_lps.homogeneous()).head<3>() - planned[id];
    EXPECT_LT((vec(row["error_robot_mm"]) - expected).norm(), 0.1) << row.dump();
  }
  // The path is more data than the landing: both parameters better determined, still agar.
  const json& with_path = vn["tissue_fit"];
  const double pse1 = with_path["standard_errors"][0], pse2 = with_path["standard_errors"][1];
  EXPECT_LT(pse1, se1) << with_path.dump();
  EXPECT_LT(pse2, se2) << with_path.dump();
  EXPECT_LT(std::abs(with_path["lambda1"].get<double>() - 0.49), 2.0 * pse1 + 1e-3)
      << with_path.dump();
  EXPECT_LT(std::abs(with_path["lambda2"].get<double>() - 0.22), 2.0 * pse2 + 1e-3)
      << with_path.dump();
  std::cout << "with one needle's path: lambda1 " << with_path["lambda1"] << " ± " << pse1
            << ", lambda2 " << with_path["lambda2"] << " ± " << pse2 << "\n";
  std::filesystem::remove_all(needle_dir);
  std::filesystem::remove(needle_dir.string() + "_truth.json");
  std::filesystem::remove_all(ct_dir);
  std::filesystem::remove(markups);
  std::filesystem::remove(truth_file);
}

}  // namespace
}  // namespace ignav::e2e
