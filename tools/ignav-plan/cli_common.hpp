// What every ignav-plan command shares: the bad-input error (exit code 2) and argument parsing.
#pragma once

#include <array>
#include <string>

namespace ignav::plan {

// Bad input from the user: printed on stderr, exit code 2.
struct CliError {
  std::string message;
};

// "X,Y,Z" -> three finite numbers; `what` names the option in errors.
std::array<double, 3> parseTriple(const std::string& text, const std::string& what);

}  // namespace ignav::plan
