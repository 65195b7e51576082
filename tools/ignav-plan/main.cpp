// ignav-plan: the offline planner. JSON on stdout; errors on stderr with exit code 2 for bad
// input and 1 for internal failures. No DDS, no server: the modules called directly.
#include <CLI/CLI.hpp>
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "confirmation_phantom.hpp"
#include "deflection_commands.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/kinematics/ik_study.hpp"
#include "ignav/kinematics/workspace_map.hpp"
#include "registration_commands.hpp"
#include "session_commands.hpp"
#include "study_report.hpp"
#include "verify_command.hpp"
#include "volume_commands.hpp"
#include "world_study.hpp"

namespace {

using ignav::config::Robot;
using ignav::kinematics::Joints;
using nlohmann::json;

constexpr double kPi = 3.14159265358979323846;
constexpr int kExitCliError = 2;
constexpr int kExitInternal = 1;

double deg(double rad) {
  return rad * 180.0 / kPi;
}

using ignav::plan::CliError;
using ignav::plan::parseTriple;
using ignav::plan::pointJson;

Robot loadRobotOrThrow(const std::string& path) {
  auto robot = ignav::config::loadRobot(path);
  if (!robot) throw CliError{robot.error().message};
  return std::move(robot).value();
}

json jointsJson(const Joints& j) {
  return {{"theta_c_deg", deg(j.theta_c_rad)}, {"z_c_mm", j.z_c_mm}, {"z_s_mm", j.z_s_mm}};
}

json forwardJson(const Robot& robot, const std::array<double, 3>& q) {
  const Joints joints{q[0] * kPi / 180.0, q[1], q[2]};
  const auto ok = robot.kinematics.checkJoints(joints);
  if (!ok) throw CliError{ok.error().message};
  const auto pose = robot.kinematics.forward(joints);
  return {{"tip_mm", pointJson(pose.tip_mm)},
          {"approach_rad", pose.approach_rad},
          {"cannula_tip_mm", pointJson(pose.cannula_tip_mm)}};
}

json inverseJson(const Robot& robot, const std::array<double, 3>& p) {
  const Eigen::Vector3d target(p[0], p[1], p[2]);
  const auto& kin = robot.kinematics;
  const auto solution = kin.inverse(target);
  if (!solution) throw CliError{solution.error().message};
  if (!solution->reachable()) {
    return {{"reachable", false},
            {"reason", ignav::kinematics::toString(solution->reach)},
            {"message", kin.describe(*solution, target)}};
  }
  const Joints& j = solution->joints;
  const auto steps = robot.transmission.toSteps(j);
  const auto cf = kin.inverseClosedForm(target);
  return {
      {"reachable", true},
      {"joints", jointsJson(j)},
      {"steps", json::array({steps.steps.motor[0], steps.steps.motor[1], steps.steps.motor[2]})},
      {"residual_mm", (kin.forward(j).tip_mm - target).norm()},
      // What whole motor steps cost: the tip error at the joints the rounded steps produce.
      {"step_quantisation_mm", (kin.forward(steps.achieved).tip_mm - target).norm()},
      {"closed_form",
       {{"joints", jointsJson(cf.joints)}, {"clipped", cf.clipped}, {"error_mm", cf.error_mm}}}};
}

int runBatch(const Robot& robot, const std::string& path) {
  std::ifstream in(path);
  if (!in) throw CliError{path + ": cannot open"};
  std::string line;
  size_t line_no = 0;
  bool any_bad = false;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    json out;
    try {
      const json case_ = json::parse(line);
      if (!case_.is_object()) throw CliError{"each line must be a JSON object"};
      if (case_.contains("id")) out["id"] = case_["id"];
      auto triple = [&](const char* key) {
        const json& v = case_.at(key);
        if (!v.is_array() || v.size() != 3)
          throw CliError{std::string(key) + ": expected [a, b, c]"};
        std::array<double, 3> t{};
        for (size_t i = 0; i < 3; ++i) {
          if (!v[i].is_number())
            throw CliError{std::string(key) + ": element " + std::to_string(i) +
                           " is not a number"};
          t[i] = v[i].get<double>();
        }
        return t;
      };
      json result;
      if (case_.contains("fk")) {
        result = forwardJson(robot, triple("fk"));
      } else if (case_.contains("ik")) {
        result = inverseJson(robot, triple("ik"));
      } else {
        throw CliError{"needs a key \"fk\": [theta_c_deg, z_c_mm, z_s_mm] or \"ik\": [x, y, z]"};
      }
      for (auto& [k, v] : result.items())
        out[k] = v;
    } catch (const CliError& e) {
      out["error"] = path + ":" + std::to_string(line_no) + ": " + e.message;
      any_bad = true;
    } catch (const json::exception& e) {
      out["error"] = path + ":" + std::to_string(line_no) + ": " + e.what();
      any_bad = true;
    }
    std::cout << out.dump() << '\n';
  }
  return any_bad ? kExitCliError : 0;
}

json workspaceJson(const Robot& robot, double grid_mm, const std::string& ply) {
  const auto w = robot.kinematics.workspace();
  const auto map = ignav::kinematics::computeWorkspaceMap(robot.kinematics, grid_mm);
  if (!map) throw CliError{"--grid-mm: " + map.error().message};
  if (!ply.empty()) {
    const auto written = ignav::kinematics::writeWorkspacePly(*map, ply);
    if (!written) throw CliError{written.error().message};
  }
  return {{"phi_deg", deg(w.exit_angle_rad)},
          {"e_phi_mm", w.exit_error_mm},
          {"volume_paper_cm3", w.volume_paper_cm3},
          {"volume_exact_cm3", w.volume_exact_cm3},
          {"volume_sampled_cm3", map->sampledVolume_cm3()},
          {"r_min_mm", w.r_min_mm},
          {"r_max_mm", w.r_max_mm},
          {"zone_diameter_paper_mm", w.zone_diameter_paper_mm},
          {"grid_mm", grid_mm},
          {"points", map->points_mm.size()}};
}

json studyJson(const Robot& robot, const std::string& out_dir) {
  using ignav::kinematics::ExitOffset;
  using ignav::kinematics::IkStudySet;
  const IkStudySet sets[] = {
      {"FK without offset (model of eqs 7-8), Rd = 550", ExitOffset::kNone, 550.0, 40.0, 40.0},
      {"FK with lateral offset, Rd = 550", ExitOffset::kLateral, 550.0, 40.0, 40.0},
      {"FK with axial offset, Rd = 550", ExitOffset::kAxial, 550.0, 40.0, 40.0},
      {"no offset, Rd = 200", ExitOffset::kNone, 200.0, 40.0, 40.0},
      {"no offset, Rd = 1000", ExitOffset::kNone, 1000.0, 40.0, 40.0},
      {"no offset, Rd = 5000", ExitOffset::kNone, 5000.0, 40.0, 40.0},
      {"no offset, zs_max = 30", ExitOffset::kNone, 550.0, 30.0, 40.0},
      {"no offset, zs_max = 25", ExitOffset::kNone, 550.0, 25.0, 40.0},
      {"no offset, zs_max = 20", ExitOffset::kNone, 550.0, 20.0, 40.0},
  };
  ignav::plan::StudyReport report;
  report.robot_name = robot.config.name;
  json rows = json::array();
  for (const auto& set : sets) {
    std::cerr << "study: " << set.label << "\n";
    report.sets.push_back(ignav::kinematics::runIkStudy(set));
    const auto& s = report.sets.back();
    rows.push_back({{"set", set.label},
                    {"targets", s.targets},
                    {"mean_mm", s.mean_mm},
                    {"max_mm", s.max_mm},
                    {"variance_mm2", s.variance_mm2},
                    {"geometries_mean_below_0_60", s.geometriesWithMeanBelow(0.60)},
                    {"clipped", s.clipped},
                    {"exact_max_mm", s.exact_max_mm}});
  }
  report.experiment_map = ignav::kinematics::closedFormErrorMap(robot.kinematics, 0.5);
  if (!out_dir.empty()) {
    const auto written = ignav::plan::writeStudyReport(report, out_dir);
    if (!written) throw CliError{written.error().message};
  }
  return {{"sets", rows}, {"out_dir", out_dir}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ignav-plan: offline kinematics, reachability and step planning (JSON out)"};
  app.require_subcommand(1);
  std::string robot_path;
  std::string joints_text, target_text, batch_path, ply_path, out_dir = "docs";
  double grid_mm = 0.5;

  auto* fk = app.add_subcommand("fk", "tip pose for joints THETA_C_DEG,ZC_MM,ZS_MM");
  fk->add_option("--robot", robot_path, "robot YAML")->required();
  fk->add_option("--joints", joints_text, "THETA_C_DEG,ZC_MM,ZS_MM")->required();
  auto* ik = app.add_subcommand("ik", "joints and motor steps for a robot-frame target X,Y,Z");
  ik->add_option("--robot", robot_path, "robot YAML")->required();
  ik->add_option("--target", target_text, "X,Y,Z in mm (robot frame)")->required();
  auto* batch = app.add_subcommand("batch", "JSON lines of {\"id\",\"fk\"|\"ik\"} cases");
  batch->add_option("--robot", robot_path, "robot YAML")->required();
  batch->add_option("--in", batch_path, "cases.jsonl")->required();
  auto* ws = app.add_subcommand("workspace", "feasible-volume figures and point cloud");
  ws->add_option("--robot", robot_path, "robot YAML")->required();
  ws->add_option("--grid-mm", grid_mm, "grid spacing of the reachability map");
  ws->add_option("--ply", ply_path, "write the reachable grid points as PLY");
  auto* study = app.add_subcommand("study", "reproduce the paper's IK simulation (MODEL.md §7)");
  study->add_option("--robot", robot_path, "robot YAML (the instrument of the heat map)")
      ->required();
  study->add_option("--out-dir", out_dir, "where IK_STUDY.md and the PNGs go ('' = none)");

  ignav::plan::VolumeInfoArgs info_args;
  std::string probe_ijk, probe_lps;
  auto* info = app.add_subcommand("volume-info", "series, geometry and HU range of a CT");
  info->add_option("path", info_args.path, "DICOM folder/file, .nrrd/.nhdr, .mha/.mhd")->required();
  info->add_option("--series", info_args.series_uid, "SeriesInstanceUID (default: largest CT)");
  info->add_option("--probe-ijk", probe_ijk, "I,J,K: add the value there");
  info->add_option("--probe-lps", probe_lps, "X,Y,Z in LPS mm: add the value there");
  info->add_flag("--fill-missing-slices", info_args.fill_missing_slices,
                 "interpolate missing slices instead of refusing the series");
  ignav::plan::RenderArgs render_args;
  std::string render_centre;
  std::vector<std::string> marks;
  auto* render = app.add_subcommand("render", "a slice as PNG, with its pixel -> LPS mapping");
  render->add_option("path", render_args.path, "DICOM folder/file, .nrrd/.nhdr, .mha/.mhd")
      ->required();
  render->add_option("--series", render_args.series_uid, "SeriesInstanceUID");
  render->add_option("--view", render_args.view, "axial | sagittal | coronal");
  render->add_option("--lps", render_centre, "X,Y,Z: the slice's centre (default: volume centre)");
  render->add_option("--out", render_args.out, "PNG path")->required();
  render->add_option("--window", render_args.window, "window width (HU)");
  render->add_option("--level", render_args.level, "window level (HU)");
  render->add_option("--size", render_args.size_px, "width and height in pixels (0 = fit)");
  render->add_option("--pixel-mm", render_args.pixel_mm, "pixel size in mm (0 = finest spacing)");
  render->add_option("--mark", marks, "X,Y,Z in LPS mm: a labelled marker (repeatable)");
  ignav::plan::PhantomArgs phantom_args;
  std::string fiducials;
  auto* phantom = app.add_subcommand("phantom", "write the built-in phantom CT as DICOM");
  phantom->add_option("out_dir", phantom_args.out_dir, "folder for the series")->required();
  phantom->add_flag("--oblique", phantom_args.oblique, "tilt the slice grid 12 degrees");
  phantom->add_option("--fiducials", fiducials, "X,Y,Z;X,Y,Z;... in LPS mm");
  phantom->add_option("--noise-hu", phantom_args.noise_hu, "Gaussian noise sigma (HU)");
  std::string phantom_dims;
  phantom->add_option("--dims", phantom_dims, "I,J,K voxels (default 96,96,64)");
  phantom->add_option("--robot", phantom_args.robot_path,
                      "robot YAML: beads at its registration feature points, robot inclined");

  ignav::plan::RegisterArgs register_args;
  std::vector<std::string> tre_targets;
  auto* reg = app.add_subcommand("register", "image -> robot transform from point pairs");
  reg->add_option("--pairs", register_args.pairs_path,
                  "JSON {\"image_mm\": [[x,y,z],...], \"robot_mm\": [[x,y,z],...]}")
      ->required();
  reg->add_flag("--rigid", register_args.rigid, "fix the scale at 1");
  reg->add_option("--robot", register_args.robot_path,
                  "robot YAML: limits, FLE, and the feature points when robot_mm is absent");
  reg->add_option("--tre", tre_targets, "X,Y,Z image mm: expected TRE there (repeatable)");
  reg->add_option("--tfm", register_args.tfm_out, "write the transform for 3D Slicer (.tfm)");
  reg->add_option("--markups", register_args.markups_out, "write the image points (.mrk.json)");
  ignav::plan::ReplayArgs replay_args;
  bool verify = false;
  auto* replay = app.add_subcommand(
      "replay", "re-derive a recorded session from its journal and check every record");
  replay->add_option("session", replay_args.session_dir, "session folder")->required();
  replay->add_option("--robot", replay_args.robot_path, "the robot YAML the server ran with")
      ->required();
  replay->add_flag("--verify", verify, "check each record's revision and phase (always done)");
  ignav::plan::VerifyArgs verify_args;
  bool verify_json = false;
  auto* verify_cmd = app.add_subcommand(
      "verify", "targeting errors of a recorded session, measured on a confirmation CT");
  verify_cmd->add_option("session", verify_args.session_dir, "session folder")->required();
  verify_cmd
      ->add_option("confirmation_ct", verify_args.confirmation_ct,
                   "DICOM folder/file, .nrrd/.nhdr, .mha/.mhd")
      ->required();
  verify_cmd->add_option("--robot", verify_args.robot_path, "the robot YAML the server ran with")
      ->required();
  verify_cmd->add_option("--reuse-sigmas", verify_args.reuse_sigmas,
                         "reuse the session's registration while no marker moved farther than "
                         "this many times the markers' localisation error (from their FREs)");
  verify_cmd->add_option("--min-localisation", verify_args.min_localisation_mm,
                         "the least localisation error (mm) taken for the markers");
  verify_cmd->add_option("--max-marker-shift", verify_args.max_marker_shift_mm,
                         "refuse a scan whose markers moved farther (mm)");
  verify_cmd->add_flag("--same-frame", verify_args.same_frame,
                       "the scan is in the session's frame: register it by the session's "
                       "registration, not its markers (a needle left in touches them)");
  verify_cmd->add_flag("--allow-extra-seeds", verify_args.allow_extra_seeds,
                       "report seeds no target claims instead of refusing them");
  verify_cmd->add_flag("--json", verify_json, "print JSON");
  verify_cmd->add_option("--markups", verify_args.markups_out,
                         "write the seeds found (.mrk.json, LPS) for 3D Slicer");
  verify_cmd->add_option("--fit-tissue", verify_args.fit_tissue_name,
                         "fit λ1, λ2 to the measured errors; NAME for the tissues.yaml entry");
  verify_cmd->add_option("--tissues", verify_args.tissues_path,
                         "tissue profiles (the needle, when the session had no tissue)");
  verify_cmd->add_option("--figure", verify_args.figure_out,
                         "write planned vs actual in the feasible volume (.png)");
  verify_cmd->add_option("--report", verify_args.report_out,
                         "write the targeting report: a table like the paper's Table V (.md)");
  ignav::plan::ConfirmationPhantomArgs confirm_args;
  bool confirm_json = false;
  auto* confirm = app.add_subcommand(
      "confirmation-phantom",
      "the confirmation CT of a session on the built-in phantom: a seed where each reached "
      "target's needle really landed");
  confirm->add_option("session", confirm_args.session_dir, "session folder")->required();
  confirm->add_option("--robot", confirm_args.robot_path, "the robot YAML the server ran with")
      ->required();
  confirm->add_option("--out", confirm_args.out_dir, "folder for the DICOM series (new or empty)")
      ->required();
  confirm->add_option("--hidden-tissue", confirm_args.hidden_tissue,
                      "a tissue profile the server is not told: the needle deflects in it "
                      "(default: none, each seed at its joints' nominal tip)");
  confirm->add_option("--tissues", confirm_args.tissues_path, "tissue profiles (YAML)");
  confirm->add_option("--world", confirm_args.world_path,
                      "a rod-in-tissue world (configs/worlds/*.yaml): the needle moves by "
                      "physics the server does not model, instead of a hidden tissue");
  confirm->add_option("--noise-hu", confirm_args.noise_hu, "the CT's Gaussian noise SD (HU)");
  confirm->add_option("--slice-mm", confirm_args.slice_mm,
                      "slice spacing and thickness (mm; default the phantom's 1.25)");
  confirm->add_option("--seed", confirm_args.seed, "the noise's seed (deterministic)");
  confirm->add_option("--needle-at", confirm_args.needle_at,
                      "the target whose needle is still in: the scan shows its cannula and "
                      "stylet (as the hidden tissue bends them) instead of its seed");
  confirm->add_option(
      "--truth", confirm_args.truth_path,
      "where the ground truth goes (JSON; default OUT_truth.json, beside the series)");
  confirm->add_flag("--json", confirm_json, "print the truth and what was written as JSON");
  confirm->footer(
      "The physical world, not the server: each reached target's seed lies where the joints the\n"
      "motion went to (nominal, or compensated when the session aimed with a tissue) land in\n"
      "the hidden tissue (extended bicycle model), mapped by the phantom's true robot -> image\n"
      "transform. The truth file holds per target planned_robot_mm, landing_robot_mm,\n"
      "landing_lps_mm and the hidden tissue; `ignav-plan verify SESSION OUT` measures it.\n");
  ignav::plan::WorldStudyArgs study_args;
  bool study_json = false;
  auto* world_study = app.add_subcommand(
      "world-study",
      "what compensation buys in a world: random targets aimed as planned, the tissue fitted "
      "from their errors, the same targets aimed again for it");
  world_study->add_option("--robot", study_args.robot_path, "the robot YAML");
  world_study->add_option("--tissues", study_args.tissues_path,
                          "tissue profiles: the needle the server models");
  world_study->add_option("--hidden-tissue", study_args.hidden_tissue,
                          "the bicycle world's tissue (\"\" leaves that world out)");
  world_study->add_option("--hidden-tissues", study_args.hidden_tissues_path,
                          "the profiles it is taken from");
  world_study->add_option("--world", study_args.world_path,
                          "the rod-in-tissue world (\"\" leaves it out)");
  world_study->add_option("--targets", study_args.targets, "how many targets (3-1000)");
  world_study->add_option("--seed", study_args.seed, "the targets' and the noise's seed");
  world_study->add_option("--localisation", study_args.localisation_mm,
                          "a seed's localisation error on the confirmation CT (mm RMS)");
  world_study->add_flag("--fit-curvature", study_args.fit_curvature,
                        "fit the needle's curvature k with λ1, λ2");
  world_study->add_flag("--json", study_json, "print JSON");
  ignav::plan::FindFiducialsArgs find_args;
  double min_hu = 0.0;
  auto* find = app.add_subcommand("find-fiducials", "locate marker beads on a CT");
  find->add_option("path", find_args.volume_path, "DICOM folder/file, .nrrd/.nhdr, .mha/.mhd")
      ->required();
  find->add_option("--series", find_args.series_uid, "SeriesInstanceUID");
  auto* min_hu_option = find->add_option("--min-hu", min_hu, "marker threshold (HU)");
  find->add_option("--expect", find_args.expect, "markers placed (without --robot)");
  find->add_option("--robot", find_args.robot_path,
                   "robot YAML: match its feature points by mutual distances and register");
  find->add_option("--tfm", find_args.tfm_out, "write the registration for 3D Slicer (.tfm)");
  find->add_option("--markups", find_args.markups_out, "write the markers (.mrk.json)");

  ignav::plan::DeflectionArgs deflection_args;
  auto* defl = app.add_subcommand("deflection", "the extended bicycle model (seed 000)");
  defl->require_subcommand(1);
  for (auto* sub : {defl->add_subcommand("simulate", "the tip path (s, z, y, γ) in soft tissue"),
                    defl->add_subcommand("fit", "λ1, λ2 from an observed path (CSV)")}) {
    sub->add_option("--k", deflection_args.needle.curvature_per_mm,
                    "signed curvature (1/mm; negative bends towards -y)")
        ->required();
    sub->add_option("--ell", deflection_args.needle.wheelbase_mm, "wheelbase (mm)")->required();
  }
  auto* defl_sim = defl->get_subcommand("simulate");
  defl_sim->add_option("--lambda1", deflection_args.tissue.lambda1)->required();
  defl_sim->add_option("--lambda2", deflection_args.tissue.lambda2)->required();
  defl_sim->add_option("--length", deflection_args.length_mm, "inserted length (mm)");
  defl_sim->add_option("--step", deflection_args.step_mm, "sample every this many mm");
  auto* defl_fit = defl->get_subcommand("fit");
  defl_fit->add_option("--in", deflection_args.csv_path, "CSV: depth_mm,deflection_mm")->required();
  defl_fit->add_flag("--fit-k", deflection_args.fit_curvature, "fit the curvature too");
  const char* noise_help =
      "depth noise the path may carry (mm): depths down to minus this, steps back up to it";
  defl_fit->add_option("--depth-noise", deflection_args.depth_noise_mm, noise_help);
  auto* defl_plot = defl->add_subcommand(
      "plot", "PNG: paths for several tissues (seed 000's Fig. 5), or observed vs fitted");
  defl_plot->add_option("--k", deflection_args.needle.curvature_per_mm)->required();
  defl_plot->add_option("--ell", deflection_args.needle.wheelbase_mm)->required();
  defl_plot->add_option("--length", deflection_args.length_mm, "inserted length (mm)");
  defl_plot->add_option("--in", deflection_args.csv_path, "observed path: plot it with the fits");
  defl_plot->add_option("--out", deflection_args.png_path, "the PNG")->required();
  defl_plot->add_option("--depth-noise", deflection_args.depth_noise_mm, noise_help);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "ignav-plan: " << e.what() << "\n";
    return kExitCliError;
  }

  try {
    if (*defl) {
      const auto out = defl_sim->parsed()    ? ignav::plan::simulateDeflection(deflection_args)
                       : defl_plot->parsed() ? ignav::plan::plotDeflection(deflection_args)
                                             : ignav::plan::fitDeflection(deflection_args);
      std::cout << out.dump(defl_sim->parsed() ? -1 : 2) << "\n";
      return 0;
    }
    if (*reg) {
      for (const auto& t : tre_targets)
        register_args.targets_image.push_back(parseTriple(t, "--tre"));
      const auto outcome = ignav::plan::registerPairs(register_args);
      std::cout << outcome.json.dump(2) << "\n";
      return outcome.exit_code;
    }
    if (*replay) {
      std::cout << ignav::plan::replaySession(replay_args).dump(2) << "\n";
      return 0;
    }
    if (*verify_cmd) {
      const auto verified = ignav::plan::verifySession(verify_args);
      std::cout << (verify_json ? verified.dump(2) + "\n"
                                : ignav::plan::verificationTable(verified));
      return 0;
    }
    if (*confirm) {
      const auto truth = ignav::plan::confirmationPhantom(confirm_args);
      std::cout << (confirm_json ? truth.dump(2) + "\n"
                                 : ignav::plan::confirmationPhantomText(truth));
      return 0;
    }
    if (*world_study) {
      const auto result = ignav::plan::worldStudy(study_args);
      std::cout << (study_json ? result.dump(2) + "\n" : ignav::plan::worldStudyText(result));
      return 0;
    }
    if (*find) {
      if (min_hu_option->count() > 0) find_args.min_hu = min_hu;
      std::cout << ignav::plan::findFiducials(find_args).dump(2) << "\n";
      return 0;
    }
    if (*info || *render || *phantom) {
      json out;
      if (*info) {
        if (!probe_ijk.empty()) info_args.probe_ijk = parseTriple(probe_ijk, "--probe-ijk");
        if (!probe_lps.empty()) info_args.probe_lps = parseTriple(probe_lps, "--probe-lps");
        out = ignav::plan::volumeInfo(info_args);
      } else if (*render) {
        if (!render_centre.empty()) render_args.centre_lps = parseTriple(render_centre, "--lps");
        for (const auto& m : marks)
          render_args.marks_lps.push_back(parseTriple(m, "--mark"));
        out = ignav::plan::render(render_args);
      } else {
        std::stringstream list(fiducials);
        for (std::string item; std::getline(list, item, ';');) {
          if (!item.empty()) phantom_args.fiducials_lps.push_back(parseTriple(item, "--fiducials"));
        }
        if (!phantom_dims.empty()) {
          const auto d = parseTriple(phantom_dims, "--dims");
          for (size_t i = 0; i < 3; ++i) {
            if (d[i] < 1 || d[i] > 2048 || d[i] != std::floor(d[i])) {
              throw CliError{"--dims: each size must be a whole number in [1, 2048]"};
            }
            phantom_args.dims[i] = static_cast<int>(d[i]);
          }
        }
        out = ignav::plan::phantom(phantom_args);
      }
      std::cout << out.dump(2) << "\n";
      return 0;
    }
    const Robot robot = loadRobotOrThrow(robot_path);
    json out;
    if (*fk) {
      out = forwardJson(robot, parseTriple(joints_text, "--joints"));
    } else if (*ik) {
      out = inverseJson(robot, parseTriple(target_text, "--target"));
    } else if (*batch) {
      return runBatch(robot, batch_path);
    } else if (*ws) {
      out = workspaceJson(robot, grid_mm, ply_path);
    } else if (*study) {
      out = studyJson(robot, out_dir);
    }
    std::cout << out.dump(2) << "\n";
    return 0;
  } catch (const CliError& e) {
    std::cerr << "ignav-plan: " << e.message << "\n";
    return kExitCliError;
  } catch (const std::exception& e) {
    std::cerr << "ignav-plan: internal error: " << e.what() << "\n";
    return kExitInternal;
  }
}
