// ignav-plan as a user runs it: a real process, JSON on stdout, exit codes.
#include <gtest/gtest.h>

#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
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

// `ignav-plan ARGS`: its exit code and stdout (and stderr with it when `with_stderr`).
ProcessResult plan(const std::string& args, bool with_stderr = false) {
  const std::string cmd =
      std::string(IGNAV_PLAN_EXE) + " " + args + (with_stderr ? " 2>&1" : " 2>/dev/null");
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

std::filesystem::path freshDir(const std::string& name) {
  const auto dir =
      std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

void writeFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

TEST(PlanCli, RegisterPrintsTheTransformOrARejection) {
  const auto dir = freshDir("ignav_cli_register");
  // robot = Rz(90°)·image + (10, 20, 30)
  writeFile(dir / "pairs.json",
            R"({"image_mm": [[0,0,0],[40,0,0],[0,30,0]],
                "robot_mm": [[10,20,30],[10,60,30],[-20,20,30]]})");
  ProcessResult run = plan("register --pairs " + (dir / "pairs.json").string() +
                           " --tre 0,0,0 --tfm " + (dir / "t.tfm").string());
  ASSERT_EQ(run.exit_code, 0) << run.out;
  json r = json::parse(run.out);
  EXPECT_TRUE(r["ok"].get<bool>());
  EXPECT_NEAR(r["scale"].get<double>(), 1.0, 1e-12);
  EXPECT_NEAR(r["rotation"][0][1].get<double>(), -1.0, 1e-12);
  EXPECT_NEAR(r["rotation"][1][0].get<double>(), 1.0, 1e-12);
  EXPECT_NEAR(r["translation_mm"][2].get<double>(), 30.0, 1e-9);
  EXPECT_LT(r["fre_mm"].get<double>(), 1e-9);
  // TRE at a fiducial's own position for a similarity fit of 3: above FLE/√3.
  EXPECT_GT(r["targets"][0]["tre_mm"].get<double>(), 0.5 / std::sqrt(3.0));
  EXPECT_TRUE(std::filesystem::exists(dir / "t.tfm"));

  const auto rejected = [&](const std::string& text, const std::string& reason) {
    writeFile(dir / "bad.json", text);
    const ProcessResult bad = plan("register --pairs " + (dir / "bad.json").string());
    EXPECT_EQ(bad.exit_code, 2) << text;
    const json j = json::parse(bad.out);
    EXPECT_FALSE(j["ok"].get<bool>());
    EXPECT_EQ(j["reason"], reason) << j.dump();
    return j["message"].get<std::string>();
  };
  rejected(R"({"image_mm": [[0,0,0],[40,0,0],[80,0,0]],
               "robot_mm": [[10,20,30],[10,60,30],[-20,20,30]]})",
           "collinear");
  rejected(R"({"image_mm": [[0,0,0],[40,0,0]], "robot_mm": [[0,0,0],[40,0,0]]})", "too_few_pairs");
  rejected("{not json", "format");
  EXPECT_NE(rejected(R"({"image_mm": [[0,0,0],[1,null,0],[0,1,0]], "robot_mm": []})", "bad_input")
                .find("image_mm[1] must hold three numbers"),
            std::string::npos);
  std::string many = R"({"robot_mm": [], "image_mm": [)";
  for (int i = 0; i < 1001; ++i)
    many += std::string(i ? "," : "") + "[0,0,0]";
  EXPECT_NE(rejected(many + "]}", "bad_input").find("image_mm has 1001 points; at most 1000"),
            std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(PlanCli, RobotPhantomFindsAndRegistersItsMarkers) {
  const auto dir = freshDir("ignav_cli_robot_phantom");
  ProcessResult run =
      plan("phantom " + (dir / "ct").string() + " --oblique --noise-hu 15 --robot " + kRobot);
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const json phantom = json::parse(run.out);
  run = plan("find-fiducials " + (dir / "ct").string() + " --robot " + kRobot + " --tfm " +
             (dir / "r.tfm").string() + " --markups " + (dir / "r.mrk.json").string());
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const json found = json::parse(run.out);
  ASSERT_TRUE(found.contains("registration")) << found.dump(2);
  const json& reg = found["registration"];
  ASSERT_TRUE(reg["ok"].get<bool>());
  // Against the phantom's true image -> robot map: every marker and the matrix agree.
  const json& truth = phantom["image_to_robot_true"];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(reg["scale"].get<double>() * reg["rotation"][r][c].get<double>(),
                  truth[r][c].get<double>(), 2e-3);
    }
    EXPECT_NEAR(reg["translation_mm"][r].get<double>(), truth[r][3].get<double>(), 0.3);
  }
  for (int k = 0; k < 3; ++k) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(found["chosen"][k]["centroid_lps_mm"][a].get<double>(),
                  phantom["fiducials_lps_mm"][k][a].get<double>(), 0.1);
    }
  }
  EXPECT_LT(reg["fre_mm"].get<double>(), 0.1);
  std::ifstream markups(dir / "r.mrk.json");
  const json m = json::parse(markups);
  EXPECT_EQ(m["markups"][0]["controlPoints"][2]["label"], "stylet_tip");
  EXPECT_TRUE(std::filesystem::exists(dir / "r.tfm"));
  EXPECT_EQ(plan("find-fiducials " + (dir / "ct").string() + " --expect 0").exit_code, 2);
  std::filesystem::remove_all(dir);
}

TEST(PlanCli, DeflectionSimulateThenFitRecoversTheTissue) {
  // The issue's CLI: a path in agar (seed 000, Table I), written as depth,deflection CSV, fitted.
  const auto sim = plan(
      "deflection simulate --k -0.0025 --ell 20 --lambda1 0.49 --lambda2 0.22 --length 130 "
      "--step 2");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const json j = json::parse(sim.out);
  EXPECT_TRUE(j["admissible"].get<bool>());
  ASSERT_EQ(j["path"].size(), 66u);
  EXPECT_EQ(j["path"][0], json::array({0.0, 0.0, 0.0, 0.0}));
  EXPECT_DOUBLE_EQ(j["path"].back()[0].get<double>(), 130.0);
  const auto dir = std::filesystem::temp_directory_path() / "ignav_deflection_cli";
  std::filesystem::create_directories(dir);
  {
    std::ofstream csv(dir / "path.csv");
    csv << "depth_mm,deflection_mm\n";
    for (std::size_t i = 1; i < j["path"].size(); ++i) {
      csv << fmt::format("{:.17g},{:.17g}\n", j["path"][i][1].get<double>(),
                         j["path"][i][2].get<double>());
    }
  }
  const auto fit = plan("deflection fit --k -0.0025 --ell 20 --in " + (dir / "path.csv").string());
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  const json f = json::parse(fit.out);
  EXPECT_NEAR(f["lambda1"].get<double>(), 0.49, 1e-6);
  EXPECT_NEAR(f["lambda2"].get<double>(), 0.22, 1e-6);
  EXPECT_EQ(f["stderr"].size(), 2u);
  EXPECT_GT(f["max_error_bicycle_mm"].get<double>(), 10 * f["max_error_mm"].get<double>());
  // The figure of observed vs fitted: a 900 x 560 PNG (its IHDR, read here byte by byte).
  const auto png = dir / "fit.png";
  const auto plot = plan("deflection plot --k -0.0025 --ell 20 --in " +
                         (dir / "path.csv").string() + " --out " + png.string());
  ASSERT_EQ(plot.exit_code, 0) << plot.out;
  std::ifstream in(png, std::ios::binary);
  std::vector<unsigned char> head(24);
  in.read(reinterpret_cast<char*>(head.data()), 24);
  EXPECT_EQ(head[1], 'P');
  EXPECT_EQ(head[2], 'N');
  EXPECT_EQ((head[18] << 8) | head[19], 900);
  EXPECT_EQ((head[22] << 8) | head[23], 560);
  EXPECT_NEAR(json::parse(plot.out)["lambda1"].get<double>(), 0.49, 1e-6);
  // An inadmissible tissue is an answer; a bad CSV line is an error naming the line.
  const auto bad = plan("deflection simulate --k -0.0025 --ell 20 --lambda1 0 --lambda2 1");
  EXPECT_EQ(bad.exit_code, 0);
  EXPECT_FALSE(json::parse(bad.out)["admissible"].get<bool>());
  std::ofstream(dir / "bad.csv") << "depth_mm,deflection_mm\n10,-1\n20,oops\n";
  const auto refused =
      plan("deflection fit --k -0.0025 --ell 20 --in " + (dir / "bad.csv").string(), true);
  const std::string& err = refused.out;
  EXPECT_EQ(refused.exit_code, 2);
  EXPECT_NE(err.find("bad.csv line 3"), std::string::npos) << err;
  std::filesystem::remove_all(dir);
}

TEST(PlanCli, DeflectionFitTakesEntryNoiseAndRefusesWhatIsNoPath) {
  // Issue 23: a measured path whose first point lies at depth −0.02 mm (noise at the entry) was
  // refused. It is data; a file holding two paths is not one path and is refused, by line.
  const auto sim = plan(
      "deflection simulate --k -0.0025 --ell 20 --lambda1 0.49 --lambda2 0.22 --length 130 "
      "--step 5");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const json path = json::parse(sim.out)["path"];
  const auto dir = std::filesystem::temp_directory_path() / "ignav_deflection_noise_cli";
  std::filesystem::create_directories(dir);
  std::string rows;
  for (std::size_t i = 1; i < path.size(); ++i)
    rows += fmt::format("{:.17g},{:.17g}\n", path[i][1].get<double>(), path[i][2].get<double>());
  std::ofstream(dir / "noisy.csv") << "depth_mm,deflection_mm\n-0.02,0.0\n" << rows;
  const auto fit = plan("deflection fit --k -0.0025 --ell 20 --in " + (dir / "noisy.csv").string());
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  EXPECT_NEAR(json::parse(fit.out)["lambda1"].get<double>(), 0.49, 1e-6);
  EXPECT_NEAR(json::parse(fit.out)["lambda2"].get<double>(), 0.22, 1e-6);
  // The tolerance is the user's: at 0.01 mm the same entry point is too far above the entry.
  EXPECT_EQ(plan("deflection fit --k -0.0025 --ell 20 --depth-noise 0.01 --in " +
                 (dir / "noisy.csv").string())
                .exit_code,
            2);
  std::ofstream(dir / "two.csv") << "depth_mm,deflection_mm\n" << rows << rows;
  const auto refused =
      plan("deflection fit --k -0.0025 --ell 20 --in " + (dir / "two.csv").string(), true);
  const std::string& err = refused.out;
  EXPECT_EQ(refused.exit_code, 2);
  EXPECT_NE(err.find("two.csv: observation 27"), std::string::npos) << err;
  EXPECT_NE(err.find("not one path"), std::string::npos) << err;
  std::filesystem::remove_all(dir);
}

TEST(PlanCli, ConfirmationPhantomRefusesWhatItCannotMakeAndSaysWhy) {
  // (A session whose targets were reached, and the output folder's refusals:
  // tests/e2e/verification_e2e_test.cpp.) Each refusal exits 2, names the cause, writes nothing.
  const auto dir = freshDir("ignav_cli_confirmation_phantom");
  const std::string tissues = std::string(IGNAV_SOURCE_DIR) + "/configs/tissues.yaml";
  const std::string out = " --out " + (dir / "ct").string();
  auto refused = [&](const std::string& args, const std::string& reason) {
    const ProcessResult run = plan("confirmation-phantom " + args + " --robot " + kRobot, true);
    EXPECT_EQ(run.exit_code, 2) << args << ": " << run.out;
    EXPECT_NE(run.out.find(reason), std::string::npos) << run.out;
    EXPECT_FALSE(std::filesystem::exists(dir / "ct")) << args;
  };
  refused((dir / "no_such_session").string() + out, "no_such_session/journal.jsonl: no journal");
  // An unknown tissue, with the names there are (before the session is even read).
  refused((dir / "no_such_session").string() + out + " --hidden-tissue jelly --tissues " + tissues,
          "tissue 'jelly' is not a profile (there are: agar, none, plastisol)");
  refused((dir / "no_such_session").string() + out + " --noise-hu -3", "--noise-hu: -3");
  // A session that only loaded its configuration: nothing was registered, nothing reached.
  std::filesystem::create_directories(dir / "unregistered");
  writeFile(dir / "unregistered" / "journal.jsonl",
            R"({"input":"config_loaded","phase":"imaging","revision":1,"t":1795586245.8,"v":2})"
            "\n");
  refused((dir / "unregistered").string() + out, "the session was never registered");
  // Registered on the phantom (the server's records of its own scan, the markers it found) and a
  // target planned, but the robot never moved: no seed.
  const auto planned = dir / "planned";
  ASSERT_EQ(plan("phantom " + (planned / "phantom_ct").string() + " --robot " + kRobot +
                 " --oblique --noise-hu 8")
                .exit_code,
            0);
  writeFile(planned / "journal.jsonl",
            R"({"input":"config_loaded","phase":"imaging","revision":1,"t":1795586245.8,"v":2}
{"client_id":"operator","input":"load_volume","path":"phantom:","phase":"imaging","request_id":1,"revision":2,"role":"planner","t":1795586246.1,"v":2}
{"description":"phantom","dims":[128,128,112],"input":"volume_loaded","phase":"registration","revision":3,"source":"phantom:","t":1795586246.2,"v":2}
{"client_id":"operator","input":"auto_fiducials","phase":"registration","request_id":2,"revision":4,"role":"planner","t":1795586246.26,"v":2}
{"input":"fiducials_detected","job":4,"path":"phantom:","phase":"planning","points":[[6.158585053950858,-15.407456080467309,51.079785483625],[1.572726955181352,-3.9382509226811635,13.057330898622126],[-1.1242165933521449,29.34596079791048,-5.448820108265366]],"revision":5,"summary":"","t":1795586246.261,"v":2}
{"client_id":"operator","input":"add_target","phase":"planning","points":[[5.132937589135416,19.1567455355339,-22.486840785845004]],"request_id":3,"revision":6,"role":"planner","t":1795586246.266,"v":2}
)");
  refused(planned.string() + out, "no target of this session was reached");
  EXPECT_EQ(plan("confirmation-phantom --robot " + kRobot + out).exit_code, 2);  // no session
  std::filesystem::remove_all(dir);
}

}  // namespace
