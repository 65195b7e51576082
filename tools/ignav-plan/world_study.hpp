// ignav-plan world-study: what compensation buys in a world (issue 40), without a server: the
// closed loop's arithmetic on many targets. Random reachable targets are aimed as planned (a first
// pass), land where the world puts them, are measured with the localisation noise of our seed
// detection, the tissue is fitted from those errors (the server's fit_tissue), and the same
// targets are aimed again with the fitted tissue (a second pass, fresh luck). Worlds: the
// extended bicycle model with a hidden tissue (the server's own model agreeing with itself) and
// a rod-in-tissue world (physics the server does not model).
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

namespace ignav::plan {

struct WorldStudyArgs {
  std::string robot_path = "configs/robots/torabi2014.yaml";
  std::string tissues_path = "configs/tissues.yaml";  // the server's needle model
  std::string hidden_tissue = "phantom_gel";          // the bicycle world's tissue ("" none)
  std::string hidden_tissues_path = "configs/demo/hidden_tissue.yaml";
  std::string world_path = "configs/worlds/layered_gel.yaml";  // the rod world ("" none)
  int targets = 24;
  std::uint64_t seed = 1;
  double localisation_mm = 0.05;  // RMS (3-D) of a seed's localisation on the confirmation CT
  bool fit_curvature = false;     // fit the needle's k with λ1, λ2
};

// Per world: the targets' errors uncompensated and compensated (mean, worst, RMS), the fit (or
// why it was refused), how many compensated aims left the robot's reach. CliError for bad input.
nlohmann::json worldStudy(const WorldStudyArgs& args);
// The same as a Markdown table with the command that made it.
std::string worldStudyText(const nlohmann::json& study);

}  // namespace ignav::plan
