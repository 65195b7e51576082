// ignav-plan deflection simulate | fit: the extended bicycle model of seed 000
// (modules/deflection).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "ignav/deflection/bicycle_model.hpp"

namespace ignav::plan {

struct DeflectionArgs {
  deflection::NeedleModel needle;
  deflection::Tissue tissue;
  double length_mm = 130.0;
  double step_mm = 1.0;
  std::string csv_path;  // fit: depth_mm,deflection_mm per line, after a header
  bool fit_curvature = false;
  double depth_noise_mm = 0.5;  // fit, plot: depth noise a measured path may carry
  std::string png_path;         // plot: where the figure goes
};

// {"admissible": true, "path": [[s, z, y, gamma], ...]}; an inadmissible tissue is an answer:
// {"admissible": false, "reason": ...}. Bad numbers throw CliError.
nlohmann::json simulateDeflection(const DeflectionArgs& args);
// {"lambda1", "lambda2", "stderr": [...], "corr", "max_error_mm", "max_error_bicycle_mm", ...}
nlohmann::json fitDeflection(const DeflectionArgs& args);
// A PNG of tip paths (depth across, deflection down): the plain model and Table I's tissues (as
// seed 000's Fig. 5), or, with a CSV, the observations with the fitted extended and plain models.
nlohmann::json plotDeflection(const DeflectionArgs& args);

}  // namespace ignav::plan
