#include "verify_command.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "ignav/compensation/compensation.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/config/tissue_profiles.hpp"
#include "ignav/registration/slicer_export.hpp"
#include "ignav/verification/confirmation_registration.hpp"
#include "ignav/verification/targeting_error.hpp"
#include "ignav/verification/targeting_report.hpp"
#include "ignav/volume/render.hpp"
#include "ignav/workflow/reducer.hpp"
#include "session_commands.hpp"

namespace ignav::plan {
namespace {

using nlohmann::json;

// 16 numbers, row-major (as the state topics show matrices).
json rowMajorJson(const Eigen::Matrix4d& m) {
  json out = json::array();
  for (int i = 0; i < 16; ++i)
    out.push_back(m(i / 4, i % 4));
  return out;
}

json stats(const verification::Stats& s) {
  return {{"count", s.count}, {"mean_mm", s.mean}, {"sd_mm", s.sd_sample},
          {"min_mm", s.min},  {"max_mm", s.max},   {"rms_mm", s.rms}};
}

// λ1, λ2 fitted to the measured landings of the targets (each at its own joints) and, where the
// scan still shows a needle, to its path (robot frame, by target id), as fit_tissue does; the
// profile as a configs/tissues.yaml entry.
json fitTissue(const VerifyArgs& args, const workflow::Session& session,
               const std::vector<verification::TargetError>& errors,
               const std::map<std::uint32_t, const workflow::Target*>& by_id,
               const std::map<std::uint32_t, std::vector<Eigen::Vector3d>>& paths_robot_mm) {
  compensation::DeflectionModel model;
  if (session.tissue) {
    model.needle = session.tissue->needle;
  } else {
    auto profiles = config::loadTissueProfiles(args.tissues_path);
    if (!profiles) throw CliError{profiles.error().message};
    model.needle = profiles->needle;
  }
  std::vector<compensation::TargetingRecord> records;
  for (const auto& e : errors) {
    records.push_back({"T" + std::to_string(e.target_id),
                       e.planned_robot_mm,
                       by_id.at(e.target_id)->reached_joints,
                       e.actual_robot_mm,
                       {}});
    if (auto path = paths_robot_mm.find(e.target_id); path != paths_robot_mm.end()) {
      records.back().path_mm = path->second;
    }
  }
  auto fit = compensation::fitTissueFromTargeting(session.robot->kinematics, model, records);
  if (!fit) throw CliError{"the tissue fit: " + fit.error().message};
  auto yaml = compensation::tissueProfileYaml(
      args.fit_tissue_name, *fit,
      fmt::format("fitted by ignav-plan verify to {} targets of session {}", records.size(),
                  session.session_id),
      false);
  if (!yaml) throw CliError{yaml.error().message};
  return {{"name", args.fit_tissue_name},
          {"lambda1", fit->tissue.lambda1},
          {"lambda2", fit->tissue.lambda2},
          {"standard_errors", fit->standard_errors},
          {"correlation", fit->correlation},
          {"rms_mm", fit->rms_mm},
          {"max_error_mm", fit->max_error_mm},
          {"rms_bicycle_mm", fit->rms_bicycle_mm},
          {"rms_no_deflection_mm", fit->rms_no_deflection_mm},
          {"limit", fit->limit},
          {"profile_yaml", *yaml}};
}

void writeMarkups(const std::string& path, const std::vector<verification::TargetError>& errors) {
  std::vector<registration::MarkupPoint> points;
  for (const auto& e : errors) {
    points.push_back(
        {"T" + std::to_string(e.target_id), e.actual_lps_mm,
         fmt::format("seed of target {}: {:.2f} mm from its plan", e.target_id, e.error_mm), true});
  }
  if (auto written = registration::writeMarkupsJson("seeds", points, path); !written) {
    throw CliError{path + ": " + written.error().message};
  }
}

// How far the model expected each target's landing to miss, as the session planned it, for the
// column beside the measured error: a compensated aim's residual (the joints moved to were
// those), else the size of the cannula's predicted sideways drift; NaN without a tissue profile.
std::map<std::uint32_t, double> predictedErrors(
    const std::map<std::uint32_t, const workflow::Target*>& by_id) {
  std::map<std::uint32_t, double> out;
  for (const auto& [id, target] : by_id) {
    out[id] = target->compensated ? target->compensated->residual_mm
                                  : std::abs(target->predicted_deviation_mm);
  }
  return out;
}

void writeFigure(const VerifyArgs& args, const workflow::Session& session,
                 const verification::Verification& verified) {
  verification::FigureOptions options;
  options.title = fmt::format("Targeting error, session {}: planned vs actual (robot frame, mm)",
                              session.session_id);
  auto png = verification::targetingFigurePng(
      verified.errors, verified.summary, verification::feasibleVolume(session.robot->kinematics),
      options);
  if (!png) throw CliError{args.figure_out + ": " + png.error().message};
  if (auto written = volume::writePng(*png, args.figure_out); !written) {
    throw CliError{args.figure_out + ": " + written.error().message};
  }
}

// The figure as the report's Markdown links it: relative to the report's folder.
std::string figureLink(const VerifyArgs& args) {
  namespace fs = std::filesystem;
  const fs::path report_dir = fs::absolute(args.report_out).parent_path();
  return fs::absolute(args.figure_out).lexically_relative(report_dir).generic_string();
}

void writeReport(const VerifyArgs& args, const workflow::Session& session,
                 const verification::Verification& verified,
                 const std::map<std::uint32_t, const workflow::Target*>& by_id, const json& out) {
  std::string md = fmt::format(
      "# Targeting error: session {}\n\n- confirmation CT: `{}`\n- registration: {}\n- seeds: "
      "{}\n\n",
      session.session_id, args.confirmation_ct, out["registration"]["message"].get<std::string>(),
      out["seeds"]["summary"].get<std::string>());
  md += verification::targetingTableMarkdown(verified.errors, verified.summary,
                                             predictedErrors(by_id));
  md += "\n" + verified.text + ".\n";
  if (!out["missing_targets"].empty()) {
    md += "\nTargets without a seed: " + out["missing_targets"].dump() + ".\n";
  }
  if (!out["extra_seeds_lps_mm"].empty()) {
    md += "\nSeeds no target claims (LPS, mm): " + out["extra_seeds_lps_mm"].dump() + ".\n";
  }
  if (out.contains("tissue_fit")) {
    const json& f = out["tissue_fit"];
    md += fmt::format(
        "\nTissue `{}` fitted to these landings: λ1 {:.3f} ± {:.3f}, λ2 {:.3f} ± {:.3f}; RMS "
        "{:.3f} mm (plain bicycle model {:.3f}, no deflection {:.3f}).\n",
        f["name"].get<std::string>(), f["lambda1"].get<double>(),
        f["standard_errors"][0].get<double>(), f["lambda2"].get<double>(),
        f["standard_errors"][1].get<double>(), f["rms_mm"].get<double>(),
        f["rms_bicycle_mm"].get<double>(), f["rms_no_deflection_mm"].get<double>());
  }
  if (!args.figure_out.empty()) {
    md += "\n![planned (blue circles) vs actual (red crosses) in the feasible volume](" +
          figureLink(args) + ")\n";
  }
  std::ofstream file(args.report_out, std::ios::trunc);
  file << md;
  file.close();
  if (!file) throw CliError{args.report_out + ": cannot write the report"};
}

}  // namespace

json verifySession(const VerifyArgs& args) {
  const workflow::Session session = replayedSession({args.session_dir, args.robot_path}).session;
  const config::Robot& robot = *session.robot;
  if (!session.registration) {
    throw CliError{args.session_dir + ": the session was never registered: nothing to verify"};
  }
  std::vector<verification::PlannedTarget> planned;
  std::map<std::uint32_t, const workflow::Target*> by_id;
  for (const auto& t : session.targets) {
    if (!t.reached) continue;
    planned.push_back({t.id, t.robot_mm});
    by_id[t.id] = &t;
  }
  if (planned.empty()) {
    throw CliError{args.session_dir +
                   ": no target of this session was reached: there are no seeds to measure"};
  }

  // The scan loaded, the robot's markers and the seeds found, as the server's load_confirmation
  // does it (workflow::measureConfirmation).
  std::optional<Eigen::Matrix4d> same_frame;
  if (args.same_frame) same_frame = session.registration->imageToRobot();
  const workflow::Input scan =
      workflow::measureConfirmation({1, args.confirmation_ct, session.robot, same_frame});
  if (scan.kind != workflow::InputKind::kConfirmationMeasured) throw CliError{scan.error};
  const std::vector<Eigen::Vector3d> model(robot.feature_points_mm.begin(),
                                           robot.feature_points_mm.end());
  auto confirmed =
      same_frame ? verification::registerConfirmationByMatrix(*same_frame,
                                                              robot.config.registration.limits)
                 : verification::registerConfirmation(
                       *session.registration, scan.points, model, robot.config.registration.kind,
                       robot.config.registration.limits,
                       {args.reuse_sigmas, args.min_localisation_mm, args.max_marker_shift_mm});
  if (!confirmed) throw CliError{args.confirmation_ct + ": " + confirmed.error().message};
  if (scan.seeds.empty()) {
    throw CliError{args.confirmation_ct + ": no seeds found (" + scan.summary + ")"};
  }
  std::vector<Eigen::Vector3d> seeds;
  for (const auto& seed : scan.seeds)
    seeds.push_back(seed.lps_mm);
  verification::MatchOptions options;
  options.allow_extra_seeds = args.allow_extra_seeds;
  auto verified = verification::verifyTargeting(planned, seeds,
                                                confirmed->registration.imageToRobot(), options);
  if (!verified) throw CliError{args.confirmation_ct + ": " + verified.error().message};

  json targets = json::array();
  std::map<std::uint32_t, std::vector<Eigen::Vector3d>> paths_robot_mm;
  const Eigen::Matrix4d image_to_robot = confirmed->registration.imageToRobot();
  for (const auto& e : verified->errors) {
    const auto* t = by_id.at(e.target_id);
    // The scan's own find at this target: a seed, or a needle's tip with its path.
    const auto found = std::find_if(scan.seeds.begin(), scan.seeds.end(), [&](const auto& seed) {
      return seed.lps_mm == e.actual_lps_mm;
    });
    const bool tip = found != scan.seeds.end() && found->kind == "tip";
    if (tip) {
      auto& path = paths_robot_mm[e.target_id];
      for (const auto& p : found->path_lps_mm)
        path.push_back((image_to_robot * p.homogeneous()).head<3>());
    }
    json row = {{"id", e.target_id},
                {"planned_robot_mm", pointJson(e.planned_robot_mm)},
                {"actual_robot_mm", pointJson(e.actual_robot_mm)},
                {"planned_lps_mm", pointJson(e.planned_lps_mm)},
                {"actual_lps_mm", pointJson(e.actual_lps_mm)},
                {"error_robot_mm", pointJson(e.error_robot_mm)},
                {"error_lps_mm", pointJson(e.error_lps_mm)},
                {"error_mm", e.error_mm},
                {"lateral_mm", e.lateral_mm},
                {"depth_mm", e.depth_mm},
                {"matched", tip ? "tip" : "seed"}};
    if (tip) {
      row["path_lps_mm"] = json::array();
      for (const auto& p : found->path_lps_mm)
        row["path_lps_mm"].push_back(pointJson(p));
    }
    row["predicted_deviation_mm"] =
        std::isfinite(t->predicted_deviation_mm) ? json(t->predicted_deviation_mm) : json();
    targets.push_back(row);
  }
  json missing = json::array();
  for (std::size_t i : verified->match.missing_targets)
    missing.push_back(planned[i].id);
  json extra = json::array();
  for (std::size_t i : verified->match.extra_seeds)
    extra.push_back(pointJson(seeds[i]));
  if (!args.markups_out.empty()) writeMarkups(args.markups_out, verified->errors);
  const auto& sum = verified->summary;
  json out = {
      {"session", args.session_dir},
      {"confirmation_ct", args.confirmation_ct},
      {"registration",
       {{"reused", confirmed->reused},
        {"by_matrix", confirmed->by_matrix},
        {"marker_shift_mm", confirmed->marker_shift_mm},
        {"fre_mm", confirmed->registration.fre_mm},
        {"image_to_robot", rowMajorJson(confirmed->registration.imageToRobot())},
        {"message", confirmed->message}}},
      {"seeds", {{"found", scan.seeds.size()}, {"summary", scan.summary}}},
      {"targets", targets},
      {"missing_targets", missing},
      {"extra_seeds_lps_mm", extra},
      {"summary",
       {{"error", stats(sum.error)}, {"lateral", stats(sum.lateral)}, {"depth", stats(sum.depth)}}},
      {"text", verified->text}};
  if (!args.fit_tissue_name.empty())
    out["tissue_fit"] = fitTissue(args, session, verified->errors, by_id, paths_robot_mm);
  if (!args.figure_out.empty()) {
    writeFigure(args, session, *verified);
    out["figure"] = args.figure_out;
  }
  if (!args.report_out.empty()) {
    writeReport(args, session, *verified, by_id, out);
    out["report"] = args.report_out;
  }
  return out;
}

std::string verificationTable(const json& v) {
  std::string out = fmt::format(
      "confirmation CT {}\n{}\n{}\n\n", v["confirmation_ct"].get<std::string>(),
      v["registration"]["message"].get<std::string>(), v["seeds"]["summary"].get<std::string>());
  out += fmt::format("{:>4}  {:>26}  {:>26}  {:>8}  {:>8}  {:>8}\n", "id", "planned (robot mm)",
                     "actual (robot mm)", "error", "lateral", "depth");
  auto p3 = [](const json& p) {
    return fmt::format("({:7.2f},{:7.2f},{:7.2f})", p[0].get<double>(), p[1].get<double>(),
                       p[2].get<double>());
  };
  for (const auto& t : v["targets"]) {
    out += fmt::format("{:>4}  {:>26}  {:>26}  {:8.2f}  {:8.2f}  {:8.2f}\n",
                       t["id"].get<unsigned>(), p3(t["planned_robot_mm"]), p3(t["actual_robot_mm"]),
                       t["error_mm"].get<double>(), t["lateral_mm"].get<double>(),
                       t["depth_mm"].get<double>());
  }
  out += "\n" + v["text"].get<std::string>() + "\n";
  if (v.contains("tissue_fit")) {
    const json& f = v["tissue_fit"];
    out += fmt::format(
        "\ntissue fitted: λ1 {:.3f} ± {:.3f}, λ2 {:.3f} ± {:.3f}; RMS {:.3f} mm (plain bicycle "
        "{:.3f}, no deflection {:.3f}){}\nfor configs/tissues.yaml:\n{}",
        f["lambda1"].get<double>(), f["standard_errors"][0].get<double>(),
        f["lambda2"].get<double>(), f["standard_errors"][1].get<double>(),
        f["rms_mm"].get<double>(), f["rms_bicycle_mm"].get<double>(),
        f["rms_no_deflection_mm"].get<double>(),
        f["limit"].get<std::string>().empty() ? "" : "; " + f["limit"].get<std::string>(),
        f["profile_yaml"].get<std::string>());
  }
  return out;
}

}  // namespace ignav::plan
