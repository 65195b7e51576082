// ignav-plan confirmation-phantom: the physical world's answer to a recorded session on the
// built-in phantom (issue 23). For every target the robot reached, a seed is deposited where the
// needle really lands: the joints the motion went to, deflected by a tissue the server was never
// told (`--hidden-tissue`, the extended bicycle model), moved by a world of elastic rods in
// layered tissue (`--world`, physics the server does not model), or at the nominal tip. The
// seeds are rendered into the same phantom (the robot's markers where the server's scan had
// them, through the phantom's TRUE robot -> image transform) with the CT's own noise and partial
// volume, written as a DICOM series, and the truth is written beside it for tests and people.
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "cli_common.hpp"

namespace ignav::plan {

struct ConfirmationPhantomArgs {
  std::string session_dir;
  std::string robot_path;     // the robot YAML the server ran with
  std::string out_dir;        // the DICOM series; must be new or empty
  std::string hidden_tissue;  // a profile of `tissues_path`; empty: no deflection
  std::string tissues_path = "configs/tissues.yaml";
  // A rod-in-tissue world (configs/worlds/*.yaml) instead of a hidden tissue: the needle moves by
  // physics the server does not model (needle_world).
  std::string world_path;
  double noise_hu = 0.0;        // Gaussian SD of the CT's noise
  double slice_mm = 0.0;        // slice spacing and thickness; 0: the phantom's own (1.25 mm)
  std::uint64_t seed = 1;       // the noise's (and the series' UIDs')
  std::uint32_t needle_at = 0;  // a target whose needle is still in (no seed); 0: none
  std::string truth_path;       // default: OUT_DIR_truth.json, beside the series
};

// Writes the series and the truth file; returns the truth (per target `id`, `planned_robot_mm`,
// `landing_robot_mm`, `landing_lps_mm`, `landing_kind` (seed | tip), ...; `hidden_tissue` with
// `name`, `lambda1`,
// `lambda2`, or null) with where it was written. CliError for bad input: the session never
// registered, no target reached, an unknown tissue (naming those there are), a --needle-at that
// names no reached target, an output folder
// that cannot be written or is not empty, a seed that would lie outside the scan.
nlohmann::json confirmationPhantom(const ConfirmationPhantomArgs& args);

// The same for a person: the scan, the hidden tissue, a line per seed.
std::string confirmationPhantomText(const nlohmann::json& truth);

}  // namespace ignav::plan
