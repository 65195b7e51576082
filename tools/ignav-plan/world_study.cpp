#include "world_study.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <random>

#include <fmt/format.h>

#include "cli_common.hpp"
#include "ignav/compensation/compensation.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/config/tissue_profiles.hpp"
#include "ignav/needle_world/rod_world.hpp"

namespace ignav::plan {
namespace {

using nlohmann::json;

// Where a needle went for joints, robot frame: the seed it leaves and its path from the skin to
// the tip (what an intermittent CT shows); `insertion` numbers the try (its luck).
struct Went {
  Eigen::Vector3d seed_mm;
  std::vector<Eigen::Vector3d> path_mm;
};
using World = std::function<Went(const kinematics::Joints&, std::uint64_t insertion)>;
// The needle detection's centreline lies within 0.15 mm of the needle (docs/VERIFICATION.md).
constexpr double kPathNoise_mm = 0.15;
// Where the insertion stops for its intermittent CT: this share of the stylet's travel.
constexpr double kPartialShare = 0.5;

json errorsJson(const std::vector<double>& e) {
  double sum = 0.0, sq = 0.0, worst = 0.0;
  for (double v : e) {
    sum += v;
    sq += v * v;
    worst = std::max(worst, v);
  }
  const auto n = static_cast<double>(e.size());
  return {{"mean_mm", sum / n}, {"worst_mm", worst}, {"rms_mm", std::sqrt(sq / n)}};
}

json study(const std::string& name, const std::string& kind, const World& world,
           const kinematics::Kinematics& kin, const deflection::NeedleModel& needle,
           const WorldStudyArgs& args) {
  // The targets: reachable, in tissue (both joints past 5 mm), the same for every world.
  std::mt19937_64 rng(args.seed);
  std::uniform_real_distribution<double> theta(0.0, 2.0 * M_PI), depth(5.0, 38.0);
  std::normal_distribution<double> noise(0.0, args.localisation_mm / std::sqrt(3.0));
  std::vector<Eigen::Vector3d> planned;
  for (int i = 0; i < args.targets; ++i)
    planned.push_back(kin.forward({theta(rng), depth(rng), depth(rng)}).tip_mm);

  // First pass, aimed as planned; measured with the detection's localisation noise.
  std::vector<compensation::TargetingRecord> records;
  std::vector<double> uncompensated;
  for (std::size_t i = 0; i < planned.size(); ++i) {
    const auto joints = kin.inverse(planned[i])->joints;
    const Eigen::Vector3d landed = world(joints, i + 1).seed_mm;
    uncompensated.push_back((landed - planned[i]).norm());
    const Eigen::Vector3d measured = landed + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    records.push_back({fmt::format("T{}", i + 1), planned[i], joints, measured, {}});
  }
  json out = {{"world", name}, {"kind", kind}, {"targets", planned.size()}};
  out["uncompensated"] = errorsJson(uncompensated);

  compensation::DeflectionModel model;  // what the server fits: its needle, the tissue unknown
  model.needle = needle;
  compensation::TargetingFitOptions fit_options;
  fit_options.fit_curvature = args.fit_curvature;
  const auto fit = compensation::fitTissueFromTargeting(kin, model, records, fit_options);
  // What the server aims with: the fitted tissue, or without one as planned (a model that does not
  // deflect: the needle's own curvature 0, no slip, so its path is the kinematics').
  compensation::DeflectionModel aim = model;
  aim.needle.curvature_per_mm = 0.0;
  std::vector<double> compensated;
  std::size_t out_of_reach = 0;
  if (fit) {
    out["fit"] = {{"lambda1", fit->tissue.lambda1},
                  {"lambda2", fit->tissue.lambda2},
                  {"standard_errors", fit->standard_errors},
                  {"rms_mm", fit->rms_mm},
                  {"rms_no_deflection_mm", fit->rms_no_deflection_mm},
                  {"rms_bicycle_mm", fit->rms_bicycle_mm}};
    aim.tissue = fit->tissue;
    aim.needle.curvature_per_mm = fit->curvature_per_mm;
    out["fit"]["curvature_per_mm"] = fit->curvature_per_mm;
  } else {
    out["fit"] = {{"refused", fit.error().reason}, {"why", fit.error().message}};
  }
  // Second pass on the same targets, fresh luck: aimed for the fitted tissue where there is one
  // (a target the compensation takes out of reach is aimed as planned, as the server does).
  std::vector<kinematics::Joints> aimed;
  for (std::size_t i = 0; i < planned.size(); ++i) {
    aimed.push_back(records[i].joints);
    if (fit) {
      if (auto c = compensation::compensate(kin, aim, planned[i])) {
        aimed.back() = c->compensated;
      } else {
        ++out_of_reach;
      }
    }
    compensated.push_back((world(aimed.back(), 1000 + i + 1).seed_mm - planned[i]).norm());
  }
  out["compensated"] = errorsJson(compensated);
  out["compensated_out_of_reach"] = out_of_reach;

  // Third pass, re-planned in the middle of each insertion: aimed as in the second, stopped with
  // half the stylet out, the needle's path on an intermittent CT (with the detection's noise),
  // the tissue refitted with that path, the rest re-aimed from it (reaimFromPath), then finished:
  // the same needle, so the same luck as its first half.
  std::normal_distribution<double> path_noise(0.0, kPathNoise_mm / std::sqrt(3.0));
  std::vector<double> replanned;
  std::size_t kept_aim = 0;
  for (std::size_t i = 0; i < planned.size(); ++i) {
    kinematics::Joints joints = aimed[i];
    const std::uint64_t insertion = 2000 + i + 1;
    kinematics::Joints partial = joints;
    partial.z_s_mm *= kPartialShare;
    Went half = world(partial, insertion);
    for (auto& p : half.path_mm)
      p += Eigen::Vector3d(path_noise(rng), path_noise(rng), path_noise(rng));
    auto with_path = records;
    with_path.push_back({"partial", planned[i], partial, half.path_mm.back(), half.path_mm});
    compensation::DeflectionModel refitted = aim;
    if (auto again = compensation::fitTissueFromTargeting(kin, model, with_path, fit_options)) {
      refitted.tissue = again->tissue;
      refitted.needle.curvature_per_mm = again->curvature_per_mm;
    }
    auto reaim = compensation::reaimFromPath(kin, refitted, partial, half.path_mm, planned[i]);
    if (reaim) {
      joints = reaim->aimed.compensated;
    } else {
      ++kept_aim;
    }
    replanned.push_back((world(joints, insertion).seed_mm - planned[i]).norm());
  }
  out["replanned"] = errorsJson(replanned);
  out["replanned_kept_aim"] = kept_aim;
  return out;
}

}  // namespace

json worldStudy(const WorldStudyArgs& args) {
  if (args.targets < 3 || args.targets > 1000) {
    throw CliError{fmt::format("--targets {}: give 3 to 1000", args.targets)};
  }
  if (!(args.localisation_mm >= 0.0) || !std::isfinite(args.localisation_mm)) {
    throw CliError{fmt::format("--localisation {}: a finite RMS ≥ 0 mm", args.localisation_mm)};
  }
  auto robot = config::loadRobot(args.robot_path);
  if (!robot) throw CliError{robot.error().message};
  const auto& kin = robot->kinematics;
  auto profiles = config::loadTissueProfiles(args.tissues_path);
  if (!profiles) throw CliError{profiles.error().message};
  const deflection::NeedleModel needle = profiles->needle;

  json worlds = json::array();
  if (!args.hidden_tissue.empty()) {
    auto hidden_profiles = config::loadTissueProfiles(args.hidden_tissues_path);
    if (!hidden_profiles) throw CliError{hidden_profiles.error().message};
    auto hidden = config::tissueProfile(*hidden_profiles, args.hidden_tissue);
    if (!hidden) throw CliError{"--hidden-tissue: " + hidden.error().message};
    const compensation::DeflectionModel model{hidden->needle, hidden->tissue,
                                              compensation::StyletCarry::kRotated};
    const World bicycle = [&](const kinematics::Joints& j, std::uint64_t) {
      auto path = compensation::predictPath(kin, model, j, 0.25, 0.0);
      if (!path) throw CliError{"the bicycle world: " + path.error().message};
      Went went{path->stylet_mm.empty() ? path->cannula_mm.back() : path->stylet_mm.back(),
                path->cannula_mm};
      went.path_mm.insert(went.path_mm.end(), path->stylet_mm.begin(), path->stylet_mm.end());
      return went;
    };
    worlds.push_back(study(fmt::format("{} (λ1 {:g}, λ2 {:g})", hidden->name,
                                       hidden->tissue.lambda1, hidden->tissue.lambda2),
                           "extended bicycle", bicycle, kin, needle, args));
  }
  if (!args.world_path.empty()) {
    auto world = needle_world::loadRodWorld(args.world_path);
    if (!world) throw CliError{"--world: " + world.error().message};
    const World rods = [&](const kinematics::Joints& j, std::uint64_t insertion) {
      auto needle_in = needle_world::insertNeedle(*world, kin, j, insertion);
      if (!needle_in) throw CliError{"the rod world: " + needle_in.error().message};
      Went went{needle_in->seed_mm, needle_in->cannula_mm};
      went.path_mm.insert(went.path_mm.end(), needle_in->stylet_mm.begin(),
                          needle_in->stylet_mm.end());
      return went;
    };
    worlds.push_back(study(world->name, "rod in tissue", rods, kin, needle, args));
  }
  return {{"robot", args.robot_path},
          {"targets", args.targets},
          {"seed", args.seed},
          {"localisation_mm", args.localisation_mm},
          {"worlds", worlds}};
}

std::string worldStudyText(const json& s) {
  std::string out = fmt::format(
      "{} random targets in tissue (seed {}), seeds measured with {:g} mm RMS localisation "
      "noise; a first pass aimed as planned, the tissue fitted from its errors, a second pass on "
      "the same targets aimed for the fitted tissue, a third re-planned in the middle of each "
      "insertion from the needle's path on an intermittent CT\n\n"
      "| world | model | uncompensated mean / worst (mm) | fit | compensated mean / worst (mm) "
      "| re-planned mid-insertion mean / worst (mm) |\n|---|---|---|---|---|---|\n",
      s["targets"].get<int>(), s["seed"].get<std::uint64_t>(), s["localisation_mm"].get<double>());
  for (const auto& w : s["worlds"]) {
    const json& f = w["fit"];
    const std::string fit =
        f.contains("refused")
            ? fmt::format("refused ({}): aimed as planned", f["refused"].get<std::string>())
            : fmt::format("λ1 {:.3f}, λ2 {:.3f}, RMS {:.3f} mm (none {:.3f})",
                          f["lambda1"].get<double>(), f["lambda2"].get<double>(),
                          f["rms_mm"].get<double>(), f["rms_no_deflection_mm"].get<double>());
    const auto out_of_reach = w["compensated_out_of_reach"].get<std::size_t>();
    out += fmt::format(
        "| {} | {} | {:.2f} / {:.2f} | {} | {:.2f} / {:.2f}{} | {:.2f} / {:.2f} |\n",
        w["world"].get<std::string>(), w["kind"].get<std::string>(),
        w["uncompensated"]["mean_mm"].get<double>(), w["uncompensated"]["worst_mm"].get<double>(),
        fit, w["compensated"]["mean_mm"].get<double>(), w["compensated"]["worst_mm"].get<double>(),
        out_of_reach > 0 ? fmt::format(" ({} out of reach once compensated)", out_of_reach)
                         : std::string(),
        w["replanned"]["mean_mm"].get<double>(), w["replanned"]["worst_mm"].get<double>());
  }
  return out;
}

}  // namespace ignav::plan
