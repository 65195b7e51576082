// ignav-plan verify: a recorded session's targeting error measured on a confirmation CT (issue
// 23), offline: the session replayed from its journal, the confirmation CT registered (the
// session's registration reused when the markers stayed, else registered anew), the seeds found
// and matched to the targets reached, and each error measured as the paper's Table V reports it.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "cli_common.hpp"

namespace ignav::plan {

struct VerifyArgs {
  std::string session_dir;
  std::string confirmation_ct;  // DICOM folder/file, .nrrd/.nhdr, .mha/.mhd
  std::string robot_path;       // the robot YAML the server ran with
  double reuse_sigmas = 3.0;    // verification::ConfirmationLimits
  double min_localisation_mm = 0.05;
  double max_marker_shift_mm = 20.0;
  bool allow_extra_seeds = false;
  // The scan is in the session's frame (the robot and the patient did not move): register it by
  // the session's registration without the markers, as where a needle left in touches them.
  bool same_frame = false;
  std::string markups_out;  // a Slicer .mrk.json of the seeds found (LPS), one per target
  // Fit the tissue (λ1, λ2 of the extended bicycle model) to the measured errors and name it: a
  // `tissues:` entry for configs/tissues.yaml comes out with the fit. The needle is the session's
  // tissue profile's, else `tissues_path`'s.
  std::string fit_tissue_name;
  std::string tissues_path = "configs/tissues.yaml";
  // The session report's artifacts: a PNG like the paper's Figs. 14-15 (planned vs actual in
  // the feasible volume) and a Markdown report with a table like its Table V.
  std::string figure_out;
  std::string report_out;
};

// Per target `id`, `planned_robot_mm`, `actual_robot_mm`, `error_mm` (and the LPS points, the
// error vectors, lateral and depth), the summary, the registration used; CliError for bad input.
nlohmann::json verifySession(const VerifyArgs& args);

// The same as a table for a person (like the paper's Table V).
std::string verificationTable(const nlohmann::json& verified);

}  // namespace ignav::plan
