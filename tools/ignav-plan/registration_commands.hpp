// ignav-plan's registration commands: register (point pairs -> transform, FRE, TRE) and
// find-fiducials (markers on a CT, matched to the robot's feature points).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli_common.hpp"

namespace ignav::plan {

struct RegisterArgs {
  std::string pairs_path;
  std::string robot_path;  // optional: limits, FLE and the model points come from it
  bool rigid = false;
  std::vector<std::array<double, 3>> targets_image;  // expected TRE at these (image mm)
  std::string tfm_out, markups_out;
};

// A rejection is a result, not an exception: {"ok": false, "reason", "message"}, exit code 2.
struct RegisterOutcome {
  nlohmann::json json;
  int exit_code = 0;
};
RegisterOutcome registerPairs(const RegisterArgs& args);

struct FindFiducialsArgs {
  std::string volume_path, series_uid;
  std::string robot_path;  // optional: match by the robot's feature points, then register
  std::optional<double> min_hu;
  std::size_t expect = 3;
  std::string markups_out, tfm_out;
};
nlohmann::json findFiducials(const FindFiducialsArgs& args);

}  // namespace ignav::plan
