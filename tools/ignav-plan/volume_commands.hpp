// ignav-plan's CT commands: volume-info, render, phantom. Each returns the JSON it prints, or
// throws CliError for bad input (exit code 2).
#pragma once

#include <array>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"

namespace ignav::plan {

struct VolumeInfoArgs {
  std::string path, series_uid;
  std::optional<std::array<double, 3>> probe_ijk, probe_lps;
  bool fill_missing_slices = false;
};
nlohmann::json volumeInfo(const VolumeInfoArgs& args);

struct RenderArgs {
  std::string path, series_uid, view = "axial", out;
  std::optional<std::array<double, 3>> centre_lps;  // default: the volume centre
  std::optional<double> window, level;
  std::vector<std::array<double, 3>> marks_lps;
  int size_px = 0;
  double pixel_mm = 0.0;  // 0: the volume's finest spacing
};
nlohmann::json render(const RenderArgs& args);

struct PhantomArgs {
  std::string out_dir;
  bool oblique = false;
  std::vector<std::array<double, 3>> fiducials_lps;  // empty: the default three
  double noise_hu = 0.0;
  std::array<int, 3> dims{0, 0, 0};  // 0: default
  std::string robot_path;  // markers at this robot's feature points instead of `fiducials_lps`
};
nlohmann::json phantom(const PhantomArgs& args);

}  // namespace ignav::plan
