#include "deflection_commands.hpp"

#include <fstream>
#include <sstream>

#include "cli_common.hpp"

namespace ignav::plan {

using nlohmann::json;

json simulateDeflection(const DeflectionArgs& args) {
  const auto admissible = deflection::checkAdmissible(args.needle, args.tissue);
  if (!admissible.admissible) return {{"admissible", false}, {"reason", admissible.reason}};
  auto path = deflection::simulate(args.needle, args.tissue, args.length_mm, args.step_mm);
  if (!path) throw CliError{path.error().message};
  json rows = json::array();
  for (const auto& p : *path)
    rows.push_back({p.s_mm, p.z_mm, p.y_mm, p.gamma_rad});
  return {{"admissible", true},
          {"k_per_mm", args.needle.curvature_per_mm},
          {"ell_mm", args.needle.wheelbase_mm},
          {"lambda1", args.tissue.lambda1},
          {"lambda2", args.tissue.lambda2},
          {"columns", {"s_mm", "z_mm", "y_mm", "gamma_rad"}},
          {"path", rows}};
}

json fitDeflection(const DeflectionArgs& args) {
  std::ifstream in(args.csv_path);
  if (!in) throw CliError{args.csv_path + ": cannot open"};
  std::vector<deflection::Observation> observed;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty() || line[0] == '#') continue;
    std::stringstream row(line);
    std::string depth, deflection_text;
    std::getline(row, depth, ',');
    std::getline(row, deflection_text, ',');
    try {
      std::size_t used_d = 0, used_y = 0;
      const double d = std::stod(depth, &used_d);
      const double y = std::stod(deflection_text, &used_y);
      observed.push_back({d, y});
    } catch (const std::exception&) {
      if (observed.empty() && number == 1) continue;  // the header
      throw CliError{args.csv_path + " line " + std::to_string(number) +
                     ": expected depth_mm,deflection_mm; got '" + line + "'"};
    }
  }
  deflection::FitOptions options;
  options.fit_curvature = args.fit_curvature;
  const auto fit = deflection::fitTissue(args.needle, observed, options);
  if (!fit) throw CliError{args.csv_path + ": " + fit.error().message};
  return {{"lambda1", fit->tissue.lambda1},
          {"lambda2", fit->tissue.lambda2},
          {"k_per_mm", fit->curvature_per_mm},
          {"stderr", fit->standard_errors},
          {"corr", fit->correlation},
          {"rms_mm", fit->rms_mm},
          {"max_error_mm", fit->max_error_mm},
          {"bicycle_k_per_mm", fit->bicycle_curvature_per_mm},
          {"max_error_bicycle_mm", fit->max_error_bicycle_mm},
          {"observations", observed.size()},
          {"iterations", fit->iterations}};
}

}  // namespace ignav::plan
