#include "cli_common.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace ignav::plan {

std::array<double, 3> parseTriple(const std::string& text, const std::string& what) {
  std::array<double, 3> v{};
  std::stringstream in(text);
  std::string item;
  std::size_t n = 0;
  while (std::getline(in, item, ',')) {
    if (n == 3) throw CliError{what + ": expected 3 comma-separated numbers, got '" + text + "'"};
    try {
      std::size_t used = 0;
      v[n] = std::stod(item, &used);
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw CliError{what + ": '" + item + "' is not a number"};
    }
    if (!std::isfinite(v[n])) throw CliError{what + ": '" + item + "' is not finite"};
    ++n;
  }
  if (n != 3) throw CliError{what + ": expected 3 comma-separated numbers, got '" + text + "'"};
  return v;
}

}  // namespace ignav::plan
