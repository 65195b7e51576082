// Re-planning during an insertion through a real server over DDS (issue 40): the first insertion
// stops part-way (pause_at); the world (ignav-plan confirmation-phantom) writes an intermittent CT
// of the needle there, bent by a tissue the server is not told; ignavctl sends it (`verify scan
// PATH same-frame`) and the server searches it on its job thread, refits the tissue with the
// needle's path and proposes a re-aim; `verify reaim` takes it, the approval request shows the
// nominal, previous and re-aimed joints, and the needle is finished. A confirmation CT then
// measures where it landed, against where the world says the aim before would have.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>

#include "server_process.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

constexpr std::uint32_t kDomain = 188;

CommandRun ctl(const std::string& args) {
  return ignavctlOn(kDomain, args);
}

json scanOf(const std::filesystem::path& session, const std::filesystem::path& out,
            const std::filesystem::path& tissues, const std::string& more = "") {
  const auto [status, text] =
      runPlan("confirmation-phantom " + session.string() +
                  " --robot " IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml --out " +
                  out.string() + " --hidden-tissue hidden_gel --tissues " + tissues.string() +
                  " --noise-hu 8 --seed 5 --json" + more,
              true);
  EXPECT_EQ(status, 0) << text;
  return json::parse(text.substr(text.find('{')));
}

json truthOf(const json& truth, std::uint32_t id) {
  for (const auto& t : truth["targets"])
    if (t["id"].get<std::uint32_t>() == id) return t;
  return json();
}

// Approves what is shown and waits until the robot rests after it.
void approveAndRest(protocol::Client& op) {
  op.waitFor([](const json& s) { return stateText(s, "approval", "status") == "pending"; }, 10s);
  const auto approved = approveShown(op);
  ASSERT_TRUE(approved.accepted) << approved.message;
  op.waitFor(
      [&](const json& s) {
        return (phaseIs(s, "at_target") || phaseIs(s, "done")) &&
               s["workflow"]["revision"].get<std::uint64_t>() > approved.revision &&
               stateText(s, "motion", "state") == "idle";
      },
      60s);
}

TEST(ReplanE2E, AnInsertionStoppedPartWayIsReaimedFromItsNeedleOnAnIntermittentCt) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("ignav_e2e_replan_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const auto tissues = dir / "hidden_tissues.yaml";
  std::ofstream(tissues) << "needle:\n  curvature_per_mm: -0.0025\n  wheelbase_mm: 20\n"
                            "tissues:\n  hidden_gel:\n    lambda1: 0.30\n    lambda2: 0.15\n"
                            "    source: the test's hidden tissue\n";
  ServerProcess server(kDomain, {"--controller-speed", "40000"});
  auto op = server.client("operator");
  const std::uint32_t first = plannedTarget(*op, {8, 12, -175});
  const auto added = op->send("add_target", {"", {lpsOf(op->state(), {-6, 10, -182})}, {}});
  ASSERT_TRUE(added.accepted) << added.message;
  const std::uint32_t second = added.target_id;
  op->waitFor([&](const json& s) { return s["targets"].contains(std::to_string(second)); }, 10s);

  // A stop part-way through ignavctl: a depth outside the stylet's is refused, half of it taken.
  const double full_mm = targetState(op->state(), first)["joints"][2].get<double>();
  const auto too_deep = ctl(fmt::format("targets pause {:.3f} {}", full_mm + 1.0, first));
  EXPECT_NE(too_deep.exit_code, 0) << too_deep.output;
  EXPECT_NE(too_deep.output.find("bad_depth"), std::string::npos) << too_deep.output;
  const auto pause = ctl(fmt::format("targets pause {:.3f} {}", full_mm / 2, first));
  ASSERT_EQ(pause.exit_code, 0) << pause.output;
  lockAndWaitForApproval(*op);
  // The server orders the targets: the other may come first.
  for (int motion = 0; motion < 2 && targetState(op->state(), first)["paused"] != true; ++motion) {
    if (op->state()["approval"]["target_id"].get<std::uint32_t>() == first) {
      EXPECT_NE(stateText(op->state(), "approval", "summary").find("part-way to T"),
                std::string::npos)
          << op->state()["approval"].dump();
    }
    approveAndRest(*op);
  }
  op->waitFor([&](const json& s) { return targetState(s, first)["paused"] == true; }, 10s);
  EXPECT_NEAR(targetState(op->state(), first)["paused_joints"][2].get<double>(), full_mm / 2, 1e-3);
  EXPECT_EQ(targetState(op->state(), first)["status"], "planned");

  // The intermittent CT of the needle where it stopped (the world's truth beside it).
  const json truth1 = scanOf(server.sessionDir(), dir / "intermittent", tissues,
                             fmt::format(" --needle-at {}", first));
  const json paused_truth = truthOf(truth1, first);
  ASSERT_TRUE(paused_truth.value("paused", false)) << truth1.dump();
  const double as_aimed_mm = paused_truth["finished_off_plan_mm"].get<double>();
  EXPECT_GT(as_aimed_mm, 1.0) << paused_truth.dump();  // the world bends it: worth re-aiming

  // Without the registration the needle's own markers cannot register the scan: refused with
  // why, the stop stays.
  const auto refused = ctl("verify scan " + (dir / "intermittent").string());
  EXPECT_NE(refused.exit_code, 0) << refused.output;
  EXPECT_NE(refused.output.find("markers_missing"), std::string::npos) << refused.output;
  op->waitFor(
      [&](const json& s) {
        return targetState(s, first)["replan"].get<std::string>().find("refused") !=
               std::string::npos;
      },
      10s);
  const auto scanned = ctl("verify scan " + (dir / "intermittent").string() + " same-frame");
  ASSERT_EQ(scanned.exit_code, 0) << scanned.output;
  EXPECT_NE(scanned.output.find("re-aim proposed"), std::string::npos) << scanned.output;
  op->waitFor(
      [&](const json& s) {
        return targetState(s, first)["replan"].get<std::string>().rfind("proposed", 0) == 0;
      },
      10s);

  const auto reaim = ctl("verify reaim");
  ASSERT_EQ(reaim.exit_code, 0) << reaim.output;
  op->waitFor(
      [&](const json& s) {
        return targetState(s, first)["reaimed"] == true &&
               stateText(s, "approval", "status") == "pending";
      },
      10s);
  const std::string summary = stateText(op->state(), "approval", "summary");
  for (const char* words :
       {"re-aimed from this needle's path", "nominal θc", "previously aimed", "re-aimed lands"}) {
    EXPECT_NE(summary.find(words), std::string::npos) << words << " in " << summary;
  }
  const json t1 = targetState(op->state(), first);
  const char* names[] = {"theta_c_rad", "z_c_mm", "z_s_mm"};
  for (int j = 0; j < 3; ++j) {  // the aim before is the one the world's scan was made against
    EXPECT_NEAR(t1["previous_joints"][j].get<double>(),
                paused_truth["aimed_joints"][names[j]].get<double>(), 1e-9)
        << t1.dump();
  }

  // Finished as re-aimed, then the rest and the retraction.
  for (int motion = 0; motion < 3 && !phaseIs(op->state(), "done"); ++motion)
    approveAndRest(*op);
  ASSERT_TRUE(phaseIs(op->state(), "done")) << op->state()["workflow"].dump();

  // Where the needle landed, measured on a confirmation CT against the world's truth.
  const json truth2 = scanOf(server.sessionDir(), dir / "confirmation", tissues);
  const auto load = op->send("load_confirmation", {(dir / "confirmation").string(), {}, {}});
  ASSERT_TRUE(load.accepted) << load.message;
  op->waitFor(
      [&](const json& s) {
        return s["workflow"]["revision"].get<std::uint64_t>() > load.revision &&
               stateText(s, "verification", "status") == "measured";
      },
      60s);
  const Eigen::Matrix4d image_to_robot = imageToRobot(op->state());
  double reaimed_mm = -1.0;
  for (const auto& row : op->state()["verification"]["targets"]) {
    if (row["target_id"].get<std::uint32_t>() != first) continue;
    const json t = truthOf(truth2, first);
    const Eigen::Vector3d truth_error =
        (image_to_robot * vec(t["landing_lps_mm"]).homogeneous()).head<3>() -
        vec(t["planned_robot_mm"]);
    EXPECT_LT((vec(row["error_robot"]) - truth_error).norm(), 0.1) << row.dump();
    reaimed_mm = row["error_mm"].get<double>();
  }
  std::cout << "T" << first << ": " << as_aimed_mm << " mm as aimed (the world's answer), "
            << reaimed_mm << " mm re-aimed mid-insertion (measured)\n";
  ASSERT_GE(reaimed_mm, 0.0);
  EXPECT_LT(reaimed_mm, 0.5 * as_aimed_mm);

  // Journaled and replayable: the session re-derived offline from its journal.
  op.reset();
  server.stop();
  const auto [status, replayed] = replayVerified(server.sessionDir());
  EXPECT_EQ(status, 0) << replayed;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace ignav::e2e
