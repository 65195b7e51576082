// ignav-plan as a user runs it: a real process, JSON on stdout, exit codes.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "ignav/config/robot_config.hpp"

namespace {

using nlohmann::json;
const std::string kRobot = std::string(IGNAV_SOURCE_DIR) + "/configs/robots/torabi2014.yaml";

struct ProcessResult {
  int exit_code;
  std::string out;
};

ProcessResult plan(const std::string& args) {
  const std::string cmd = std::string(IGNAV_PLAN_EXE) + " " + args + " 2>/dev/null";
  FILE* pipe = popen(cmd.c_str(), "r");
  std::string out;
  std::array<char, 4096> buf{};
  size_t n = 0;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0)
    out.append(buf.data(), n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

TEST(PlanCli, ForwardThenInverseRoundTrips) {
  const ProcessResult fk = plan("fk --robot " + kRobot + " --joints 30,12.5,22");
  ASSERT_EQ(fk.exit_code, 0);
  const json pose = json::parse(fk.out);
  const auto tip = pose["tip_mm"];
  ASSERT_EQ(tip.size(), 3u);
  char target[128];
  std::snprintf(target, sizeof target, "%.17g,%.17g,%.17g", tip[0].get<double>(),
                tip[1].get<double>(), tip[2].get<double>());
  const ProcessResult ik = plan("ik --robot " + kRobot + " --target " + target);
  ASSERT_EQ(ik.exit_code, 0);
  const json sol = json::parse(ik.out);
  EXPECT_TRUE(sol["reachable"].get<bool>());
  EXPECT_NEAR(sol["joints"]["theta_c_deg"].get<double>(), 30.0, 1e-9);
  EXPECT_NEAR(sol["joints"]["z_c_mm"].get<double>(), 12.5, 1e-9);
  EXPECT_NEAR(sol["joints"]["z_s_mm"].get<double>(), 22.0, 1e-9);
  EXPECT_LT(sol["residual_mm"].get<double>(), 1e-9);
  // Casing coupling by hand: 30° is 53.33 -> 53 steps on the spline nut; the screw nut turns
  // those 53 plus 12.5 mm x 640/1.5875 = 5039.4 -> 5039 for the translation.
  EXPECT_EQ(sol["steps"][1].get<long>(), 53);
  EXPECT_EQ(sol["steps"][0].get<long>(), 53 + 5039);
  EXPECT_GT(sol["closed_form"]["error_mm"].get<double>(), 0.0);
}

TEST(PlanCli, UnreachableIsAnAnswerNotAnError) {
  const ProcessResult ik = plan("ik --robot " + kRobot + " --target 30,0,-180");
  ASSERT_EQ(ik.exit_code, 0);
  const json sol = json::parse(ik.out);
  EXPECT_FALSE(sol["reachable"].get<bool>());
  EXPECT_EQ(sol["reason"], "beyond_max_radius");
  EXPECT_NE(sol["message"].get<std::string>().find("beyond the maximum radius"), std::string::npos);
}

TEST(PlanCli, BadInputExitsWithTwo) {
  EXPECT_EQ(plan("ik --robot " + kRobot + " --target 1,2").exit_code, 2);
  EXPECT_EQ(plan("ik --robot " + kRobot + " --target 1,nan,3").exit_code, 2);
  EXPECT_EQ(plan("fk --robot " + kRobot + " --joints 0,50,0").exit_code, 2);  // zc beyond travel
  EXPECT_EQ(plan("fk --robot /nonexistent.yaml --joints 0,0,0").exit_code, 2);
  EXPECT_EQ(plan("warp --robot " + kRobot).exit_code, 2);
  EXPECT_EQ(plan("workspace --robot " + kRobot + " --grid-mm 0").exit_code, 2);
}

TEST(PlanCli, BatchAnswersEveryLineInOrder) {
  const auto path = std::filesystem::temp_directory_path() / "ignav_batch_test.jsonl";
  {
    std::ofstream f(path);
    f << R"({"id": "a", "fk": [0, 0, 0]})"
      << "\n"
      << R"({"id": 7, "ik": [0, 10, -160]})"
      << "\n"
      << R"({"id": "bad", "ik": [0, "x", -160]})"
      << "\n"
      << R"({"id": "far", "ik": [0, 40, -160]})"
      << "\n";
  }
  const ProcessResult run = plan("batch --robot " + kRobot + " --in " + path.string());
  EXPECT_EQ(run.exit_code, 2);  // one bad line
  std::istringstream lines(run.out);
  std::vector<json> out;
  for (std::string l; std::getline(lines, l);)
    out.push_back(json::parse(l));
  ASSERT_EQ(out.size(), 4u);
  EXPECT_EQ(out[0]["id"], "a");
  EXPECT_NEAR(out[0]["tip_mm"][1].get<double>(), 1.8030, 5e-5);
  EXPECT_EQ(out[1]["id"], 7);
  EXPECT_TRUE(out[1]["reachable"].get<bool>());
  EXPECT_TRUE(out[2].contains("error"));
  EXPECT_EQ(out[3]["reason"], "beyond_max_radius");
  std::filesystem::remove(path);
}

TEST(PlanCli, WorkspaceFiguresAndPointCloud) {
  const auto ply = std::filesystem::temp_directory_path() / "ignav_cli_ws.ply";
  const ProcessResult run =
      plan("workspace --robot " + kRobot + " --grid-mm 1 --ply " + ply.string());
  ASSERT_EQ(run.exit_code, 0);
  const json w = json::parse(run.out);
  EXPECT_NEAR(w["phi_deg"].get<double>(), 11.4, 0.05);
  EXPECT_NEAR(w["volume_paper_cm3"].get<double>(), 51.53, 0.005);
  EXPECT_NEAR(w["zone_diameter_paper_mm"].get<double>(), 40.5, 0.005);
  EXPECT_GT(w["points"].get<long>(), 80000);
  EXPECT_TRUE(std::filesystem::exists(ply));
  std::filesystem::remove(ply);
}

TEST(PlanCli, PhantomVolumeInfoAndRenderAClick) {
  const auto dir = std::filesystem::temp_directory_path() / "ignav_cli_phantom";
  std::filesystem::remove_all(dir);
  ProcessResult run =
      plan("phantom " + dir.string() + " --dims 48,40,32 --fiducials '0,0,0;8,-5,6;-9,7,-4'");
  ASSERT_EQ(run.exit_code, 0);
  EXPECT_EQ(json::parse(run.out)["files"], 32);
  run = plan("volume-info " + dir.string() + " --probe-lps 8,-5,6 --probe-ijk 0,0,0");
  ASSERT_EQ(run.exit_code, 0);
  const json info = json::parse(run.out);
  EXPECT_EQ(info["dims"], json::array({48, 40, 32}));
  EXPECT_EQ(info["modality"], "CT");
  EXPECT_EQ(info["series"].size(), 1u);
  EXPECT_GT(info["probe_lps"]["value"].get<double>(), 2000.0);  // inside a fiducial bead
  // A 38 x 31 x 39 mm grid lies inside the 60 x 60 x 64 mm gelatin box: its corner is gelatin.
  EXPECT_EQ(info["probe_ijk"]["value"].get<double>(), 20.0);
  EXPECT_EQ(info["hu_max"].get<double>(), 3000.0);
  // Render a slice through a fiducial and map its marker's pixel back to LPS with the printed
  // matrix: the click lands on the fiducial.
  const auto png = dir / "slice.png";
  run = plan("render " + dir.string() + " --view coronal --lps 8,-5,6 --mark 8,-5,6 --out " +
             png.string());
  ASSERT_EQ(run.exit_code, 0);
  const json r = json::parse(run.out);
  EXPECT_TRUE(std::filesystem::exists(png));
  const double u = r["marks"][0]["pixel"][0], v = r["marks"][0]["pixel"][1];
  const json& m = r["pixel_to_lps"];
  const double lps[3] = {
      m[0][0].get<double>() * u + m[0][1].get<double>() * v + m[0][3].get<double>(),
      m[1][0].get<double>() * u + m[1][1].get<double>() * v + m[1][3].get<double>(),
      m[2][0].get<double>() * u + m[2][1].get<double>() * v + m[2][3].get<double>()};
  EXPECT_NEAR(lps[0], 8.0, 1e-9);
  EXPECT_NEAR(lps[1], -5.0, 1e-9);
  EXPECT_NEAR(lps[2], 6.0, 1e-9);
  EXPECT_EQ(plan("volume-info /nonexistent/ct").exit_code, 2);
  EXPECT_EQ(plan("render " + dir.string() + " --view upside --out x.png").exit_code, 2);
  std::filesystem::remove_all(dir);
}

}  // namespace
