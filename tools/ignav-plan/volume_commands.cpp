#include "volume_commands.hpp"

#include <cmath>
#include <iostream>
#include <sstream>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/load.hpp"
#include "ignav/volume/phantom.hpp"
#include "ignav/volume/render.hpp"

namespace ignav::plan {
namespace {

using nlohmann::json;
using volume::LoadedVolume;

LoadedVolume load(const std::string& path, const std::string& uid, bool fill) {
  volume::DicomLoadOptions options;
  options.series_uid = uid;
  options.fill_missing_slices = fill;
  std::size_t last_decile = 0;
  options.progress = [&](const volume::Progress& p) {
    // Long loads: a line per 10 % on stderr, so stdout stays pure JSON.
    if (p.total < 50) return;
    const std::size_t decile = p.done * 10 / p.total;
    if (decile != last_decile || p.done == 0) {
      std::cerr << "load: " << p.stage << " " << p.done << "/" << p.total << "\n";
      last_decile = decile;
    }
  };
  auto v = volume::loadVolume(path, options);
  if (!v) throw CliError{v.error().message};
  return std::move(v).value();
}

}  // namespace

json volumeInfo(const VolumeInfoArgs& args) {
  const LoadedVolume loaded = load(args.path, args.series_uid, args.fill_missing_slices);
  const volume::Volume& v = loaded.volume;
  const volume::Geometry& g = v.geometry;
  json series = json::array();
  for (const auto& s : loaded.series) {
    series.push_back({{"uid", s.uid},
                      {"modality", s.modality},
                      {"description", s.description},
                      {"files", s.files},
                      {"frames", s.frames}});
  }
  const auto [lo, hi] = v.valueRange();
  json out = {{"series", series},
              {"series_uid", v.series_uid},
              {"modality", v.modality},
              {"dims", {g.dims[0], g.dims[1], g.dims[2]}},
              {"spacing_mm", {g.spacing_mm.x(), g.spacing_mm.y(), g.spacing_mm.z()}},
              {"ijk_to_lps", matrixRowsJson(g.ijkToLps())},
              {"hu_min", lo},
              {"hu_max", hi},
              {"warnings", loaded.warnings},
              {"notes", loaded.notes}};
  if (args.probe_ijk) {
    const auto& p = *args.probe_ijk;
    const Eigen::Vector3d ijk(p[0], p[1], p[2]);
    const double value = v.sampleIjk(ijk, NAN);
    out["probe_ijk"] = {{"ijk", p},
                        {"lps_mm", {g.toLps(ijk).x(), g.toLps(ijk).y(), g.toLps(ijk).z()}},
                        {"value", std::isnan(value) ? json(nullptr) : json(value)}};
  }
  if (args.probe_lps) {
    const auto& p = *args.probe_lps;
    const Eigen::Vector3d lps(p[0], p[1], p[2]);
    const Eigen::Vector3d ijk = g.toIjk(lps);
    const double value = v.sampleLps(lps, NAN);
    out["probe_lps"] = {{"lps_mm", p},
                        {"ijk", {ijk.x(), ijk.y(), ijk.z()}},
                        {"value", std::isnan(value) ? json(nullptr) : json(value)}};
  }
  return out;
}

json render(const RenderArgs& args) {
  const LoadedVolume loaded = load(args.path, args.series_uid, false);
  volume::SliceSpec spec;
  if (args.view == "axial") {
    spec.view = volume::View::kAxial;
  } else if (args.view == "sagittal") {
    spec.view = volume::View::kSagittal;
  } else if (args.view == "coronal") {
    spec.view = volume::View::kCoronal;
  } else {
    throw CliError{"--view: '" + args.view + "' is not one of axial, sagittal, coronal"};
  }
  spec.centre_lps_mm =
      args.centre_lps
          ? Eigen::Vector3d((*args.centre_lps)[0], (*args.centre_lps)[1], (*args.centre_lps)[2])
          : volume::volumeCentreLps(loaded.volume.geometry);
  spec.width_px = spec.height_px = args.size_px;
  spec.pixel_size_mm = args.pixel_mm;
  if (args.window) spec.window.width = *args.window;
  if (args.level) spec.window.level = *args.level;
  if (!(spec.window.width > 0.0)) throw CliError{"--window: must be positive"};
  const auto slice = volume::reslice(loaded.volume, spec);
  if (!slice) throw CliError{slice.error().message};
  volume::Overlays overlays;
  int n = 0;
  for (const auto& m : args.marks_lps) {
    overlays.points.push_back({Eigen::Vector3d(m[0], m[1], m[2]), "M" + std::to_string(++n)});
  }
  const auto png = volume::renderPng(*slice, overlays);
  if (!png) throw CliError{png.error().message};
  if (auto ok = volume::writePng(*png, args.out); !ok) throw CliError{ok.error().message};
  const Eigen::Matrix4d& m = slice->pixel_to_lps;
  json marks = json::array();
  for (const auto& p : overlays.points) {
    const Eigen::Vector3d uvd = slice->lpsToPixel(p.lps_mm);
    marks.push_back({{"label", p.label}, {"pixel", {uvd.x(), uvd.y()}}, {"distance_mm", uvd.z()}});
  }
  return {{"png", args.out},
          {"width", slice->width},
          {"height", slice->height},
          {"pixel_size_mm", slice->pixel_size_mm},
          // LPS = pixel_to_lps · (u, v, 0, 1): u = column, v = row, pixel centres at integers.
          {"pixel_to_lps", matrixRowsJson(m)},
          {"window", {{"width", slice->window.width}, {"level", slice->window.level}}},
          {"marks", marks}};
}

json phantom(const PhantomArgs& args) {
  volume::PhantomSpec spec;
  json robot_json;
  if (!args.robot_path.empty()) {
    if (!args.fiducials_lps.empty()) throw CliError{"--fiducials and --robot exclude each other"};
    auto robot = config::loadRobot(args.robot_path);
    if (!robot) throw CliError{robot.error().message};
    auto rp = registration::makeRobotPhantom(robot->kinematics, robot->config.registration.scan);
    if (!rp) throw CliError{rp.error().message};
    spec = rp->spec;
    json model = json::array();
    for (const auto& p : rp->model_robot_mm)
      model.push_back({p.x(), p.y(), p.z()});
    robot_json = {{"robot", robot->config.name},
                  {"feature_points_robot_mm", model},
                  {"image_to_robot_true", matrixRowsJson(rp->image_to_robot_true)}};
  }
  spec.oblique = args.oblique;
  spec.noise_sigma_hu = args.noise_hu;
  if (!args.fiducials_lps.empty()) {
    spec.fiducials_lps_mm.clear();
    for (const auto& f : args.fiducials_lps)
      spec.fiducials_lps_mm.emplace_back(f[0], f[1], f[2]);
  }
  if (args.dims[0] > 0) spec.dims = args.dims;
  const auto v = volume::makePhantom(spec);
  if (!v) throw CliError{v.error().message};
  const auto files = volume::writeDicomSeries(*v, args.out_dir);
  if (!files) throw CliError{files.error().message};
  json fiducials = json::array();
  for (const auto& f : spec.fiducials_lps_mm)
    fiducials.push_back({f.x(), f.y(), f.z()});
  json out = {{"out_dir", args.out_dir},
              {"files", files->size()},
              {"dims", {spec.dims[0], spec.dims[1], spec.dims[2]}},
              {"fiducials_lps_mm", fiducials},
              {"ijk_to_lps", matrixRowsJson(v->geometry.ijkToLps())}};
  if (!robot_json.is_null()) out.update(robot_json);
  return out;
}

}  // namespace ignav::plan
