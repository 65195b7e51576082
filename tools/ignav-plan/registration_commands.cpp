#include "registration_commands.hpp"

#include <cmath>
#include <fstream>

#include <fmt/format.h>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/fiducial_detection.hpp"
#include "ignav/registration/point_registration.hpp"
#include "ignav/registration/slicer_export.hpp"
#include "ignav/volume/load.hpp"

namespace ignav::plan {
namespace {

using nlohmann::json;
using Points = std::vector<Eigen::Vector3d>;

constexpr std::size_t kMaxPairs = 1000;

// Feature-point names when the robot supplied the model points, else P1, P2, ...
std::string pointLabel(std::size_t i, bool feature_points) {
  if (feature_points && i < 3) {
    return registration::toString(static_cast<registration::FeaturePoint>(i));
  }
  return "P" + std::to_string(i + 1);
}

// Errors name the file and the element, e.g. "pairs.json: image_mm[2] must be [x, y, z]".
Points readPoints(const json& doc, const std::string& key, const std::string& source) {
  const json& a = doc.at(key);
  if (!a.is_array()) throw CliError{source + ": " + key + " must be an array of [x, y, z]"};
  if (a.size() > kMaxPairs) {
    throw CliError{source + ": " + key + " has " + std::to_string(a.size()) + " points; at most " +
                   std::to_string(kMaxPairs)};
  }
  Points points;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const std::string where = source + ": " + key + "[" + std::to_string(i) + "]";
    if (!a[i].is_array() || a[i].size() != 3) throw CliError{where + " must be [x, y, z]"};
    Eigen::Vector3d p;
    for (int c = 0; c < 3; ++c) {
      // JSON has no NaN; null is what a NaN becomes in most writers.
      if (!a[i][c].is_number()) throw CliError{where + " must hold three numbers"};
      p[c] = a[i][c].get<double>();
    }
    points.push_back(p);
  }
  return points;
}

std::optional<config::Robot> loadOptionalRobot(const std::string& path) {
  if (path.empty()) return std::nullopt;
  auto robot = config::loadRobot(path);
  if (!robot) throw CliError{robot.error().message};
  return std::move(robot).value();
}

json registrationJson(const registration::Registration& r,
                      const registration::RegistrationSettings& settings) {
  json rotation = json::array();
  for (int i = 0; i < 3; ++i)
    rotation.push_back({r.rotation(i, 0), r.rotation(i, 1), r.rotation(i, 2)});
  const auto n = r.image_mm.size();
  return {{"ok", true},
          {"kind", registration::toString(r.kind)},
          {"scale", r.scale},
          {"rotation", rotation},
          {"translation_mm", pointJson(r.translation_mm)},
          {"fre_mm", r.fre_mm},
          {"residuals_mm", r.residuals_mm},
          {"fle_mm", settings.fle_mm},
          {"expected_fre_mm", registration::expectedFre_mm(n, settings.fle_mm, r.kind)},
          {"fle_estimate_from_fre_mm", registration::estimatedFle_mm(n, r.fre_mm, r.kind)}};
}

json targetsJson(const registration::Registration& r,
                 const registration::RegistrationSettings& settings,
                 const std::vector<std::array<double, 3>>& targets) {
  const auto fiducials = registration::describeFiducials(r.image_mm);
  json out = json::array();
  for (const auto& t : targets) {
    const Eigen::Vector3d image(t[0], t[1], t[2]);
    const double tre = registration::expectedTre_mm(fiducials, image, settings.fle_mm, r.kind);
    json row = {
        {"image_mm", pointJson(image)}, {"robot_mm", pointJson(r.toRobot(image))}, {"tre_mm", tre}};
    if (tre > settings.max_tre_mm) {
      row["warning"] =
          fmt::format("expected TRE {:.2f} mm exceeds {:.2f} mm", tre, settings.max_tre_mm);
    }
    out.push_back(row);
  }
  return out;
}

void writeMarkups(const std::vector<registration::MarkupPoint>& points, const std::string& path) {
  if (path.empty()) return;
  if (auto s = registration::writeMarkupsJson("ignav registration points", points, path); !s) {
    throw CliError{s.error().message};
  }
}

void writeExports(const registration::Registration& r, bool feature_points, const std::string& tfm,
                  const std::string& markups) {
  if (!tfm.empty()) {
    if (auto s = registration::writeItkTransform(r, tfm); !s) throw CliError{s.error().message};
  }
  std::vector<registration::MarkupPoint> points;
  for (std::size_t i = 0; i < r.image_mm.size(); ++i) {
    points.push_back({pointLabel(i, feature_points), r.image_mm[i],
                      fmt::format("registration residual {:.3f} mm", r.residuals_mm[i]), true});
  }
  writeMarkups(points, markups);
}

}  // namespace

RegisterOutcome registerPairs(const RegisterArgs& args) {
  auto reject = [](const std::string& reason, const std::string& message) {
    return RegisterOutcome{{{"ok", false}, {"reason", reason}, {"message", message}}, 2};
  };
  try {
    const auto robot = loadOptionalRobot(args.robot_path);
    registration::RegistrationSettings settings;
    if (robot) settings = robot->config.registration;
    if (args.rigid) settings.kind = registration::TransformKind::kRigid;

    std::ifstream in(args.pairs_path, std::ios::binary);
    if (!in) return reject("io", args.pairs_path + ": cannot open");
    const json doc = json::parse(in, nullptr, /*allow_exceptions=*/false);
    if (doc.is_discarded() || !doc.is_object()) {
      return reject("format", args.pairs_path + ": not a JSON object");
    }
    if (!doc.contains("image_mm"))
      return reject("format", args.pairs_path + ": image_mm is missing");
    const Points image = readPoints(doc, "image_mm", args.pairs_path);
    Points model;
    if (doc.contains("robot_mm")) {
      model = readPoints(doc, "robot_mm", args.pairs_path);
    } else if (robot) {
      // The user clicked the three feature points; the robot says where they are.
      model.assign(robot->feature_points_mm.begin(), robot->feature_points_mm.end());
    } else {
      return reject("format", args.pairs_path +
                                  ": robot_mm is missing (or give --robot to use "
                                  "the robot's feature points)");
    }
    auto r = registration::registerPoints(image, model, settings.kind, settings.limits);
    if (!r) {
      return reject(r.error().reason.empty() ? toString(r.error().code) : r.error().reason,
                    r.error().message);
    }
    json out = registrationJson(*r, settings);
    if (!args.targets_image.empty()) out["targets"] = targetsJson(*r, settings, args.targets_image);
    writeExports(*r, !doc.contains("robot_mm"), args.tfm_out, args.markups_out);
    return {out, 0};
  } catch (const CliError& e) {
    return reject("bad_input", e.message);
  }
}

json findFiducials(const FindFiducialsArgs& args) {
  if (!args.tfm_out.empty() && args.robot_path.empty()) {
    throw CliError{
        "--tfm needs --robot: the transform registers the markers to its feature points"};
  }
  const auto robot = loadOptionalRobot(args.robot_path);
  registration::RegistrationSettings settings;
  if (robot) settings = robot->config.registration;
  auto search = settings.fiducials;
  if (args.min_hu) search.min_hu = *args.min_hu;
  search.expect = args.expect;

  volume::DicomLoadOptions options;
  options.series_uid = args.series_uid;
  auto loaded = volume::loadVolume(args.volume_path, options);
  if (!loaded) throw CliError{loaded.error().message};
  Points model;
  if (robot) model.assign(robot->feature_points_mm.begin(), robot->feature_points_mm.end());
  auto found = registration::findFiducials(loaded->volume, search, model);
  if (!found) throw CliError{found.error().message};

  json candidates = json::array();
  for (const auto& c : found->candidates) {
    json row = {{"centroid_lps_mm", pointJson(c.centroid_lps_mm)},
                {"voxels", c.voxel_count},
                {"volume_mm3", c.volume_mm3},
                {"extent_mm", c.extent_mm},
                {"peak_hu", c.peak_hu}};
    if (c.rejected.empty()) {
      row["background_hu"] = c.background_hu;
    } else {
      row["rejected"] = c.rejected;
    }
    candidates.push_back(row);
  }
  json out = {{"summary", found->summary},
              {"bright_voxels", found->bright_voxels},
              {"min_hu", search.min_hu},
              {"candidates", candidates}};
  if (!found->match) {
    // Nothing chosen: the bead-like candidates are still worth looking at in Slicer.
    std::vector<registration::MarkupPoint> points;
    for (const auto& c : found->candidates) {
      if (c.rejected.empty()) {
        points.push_back({"candidate " + std::to_string(points.size() + 1), c.centroid_lps_mm,
                          fmt::format("{:.1f} mm³, peak {:.0f} HU", c.volume_mm3, c.peak_hu),
                          false});
      }
    }
    writeMarkups(points, args.markups_out);
    return out;
  }

  const auto& m = *found->match;
  json chosen = json::array();
  Points image;
  for (std::size_t k = 0; k < m.candidate.size(); ++k) {
    const auto& c = found->candidates[m.candidate[k]];
    image.push_back(c.centroid_lps_mm);
    chosen.push_back({{"label", pointLabel(k, robot.has_value())},
                      {"candidate", m.candidate[k]},
                      {"centroid_lps_mm", pointJson(c.centroid_lps_mm)}});
  }
  out["chosen"] = chosen;
  if (robot) {
    out["match"] = {{"rms_residual_mm", m.rms_residual_mm},
                    {"distance_residuals_mm", m.distance_residuals_mm},
                    {"runner_up_rms_mm",
                     std::isfinite(m.runner_up_rms_mm) ? json(m.runner_up_rms_mm) : json(nullptr)}};
    auto r = registration::registerPoints(image, model, settings.kind, settings.limits);
    if (r) {
      out["registration"] = registrationJson(*r, settings);
      writeExports(*r, true, args.tfm_out, args.markups_out);
      return out;
    }
    out["registration"] = {
        {"ok", false}, {"reason", r.error().reason}, {"message", r.error().message}};
  }
  std::vector<registration::MarkupPoint> points;
  for (std::size_t k = 0; k < image.size(); ++k) {
    points.push_back({pointLabel(k, robot.has_value()), image[k], "detected", false});
  }
  writeMarkups(points, args.markups_out);
  return out;
}

}  // namespace ignav::plan
