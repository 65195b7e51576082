// What every ignav-plan command shares: the bad-input error (exit code 2) and argument parsing.
#pragma once

#include <array>
#include <string>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace ignav::plan {

// Bad input from the user: printed on stderr, exit code 2.
struct CliError {
  std::string message;
};

// "X,Y,Z" -> three finite numbers; `what` names the option in errors.
std::array<double, 3> parseTriple(const std::string& text, const std::string& what);

// A point as the JSON output shows it: [x, y, z].
inline nlohmann::json pointJson(const Eigen::Vector3d& p) {
  return nlohmann::json::array({p.x(), p.y(), p.z()});
}

// A 4 x 4 matrix as rows: [[m00, m01, m02, m03], ...].
inline nlohmann::json matrixRowsJson(const Eigen::Matrix4d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r)
    rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

}  // namespace ignav::plan
