#include "deflection_commands.hpp"

#include <algorithm>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <tuple>

#include <fmt/format.h>

#include "cli_common.hpp"
#include "ignav/volume/render.hpp"

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

namespace {

std::vector<deflection::Observation> readObservations(const std::string& csv_path) {
  std::ifstream in(csv_path);
  if (!in) throw CliError{csv_path + ": cannot open"};
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
      throw CliError{csv_path + " line " + std::to_string(number) +
                     ": expected depth_mm,deflection_mm; got '" + line + "'"};
    }
  }
  return observed;
}

struct Curve {
  std::string label;
  std::vector<cv::Point2d> zy_mm;
  cv::Scalar bgr;
  bool points = false;
};

void savePlot(const std::vector<Curve>& curves, const std::string& title, const std::string& path) {
  const int w = 900, h = 560, left = 80, right = 30, top = 50, bottom = 60;
  double z_hi = 1.0, y_lo = 0.0, y_hi = 0.0;
  for (const auto& c : curves) {
    for (const auto& p : c.zy_mm) {
      z_hi = std::max(z_hi, p.x);
      y_lo = std::min(y_lo, p.y);
      y_hi = std::max(y_hi, p.y);
    }
  }
  if (y_hi - y_lo < 1.0) y_lo = y_hi - 1.0;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  auto at = [&](const cv::Point2d& p) {
    return cv::Point(left + static_cast<int>((p.x / z_hi) * (w - left - right)),
                     top + static_cast<int>((y_hi - p.y) / (y_hi - y_lo) * (h - top - bottom)));
  };
  auto text = [&](const std::string& t, cv::Point o, double scale = 0.45) {
    cv::putText(img, t, o, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(20, 20, 20), 1, cv::LINE_AA);
  };
  cv::rectangle(img, at({0, y_hi}), at({z_hi, y_lo}), cv::Scalar(120, 120, 120));
  for (int i = 0; i <= 4; ++i) {
    const double z = z_hi * i / 4, y = y_lo + (y_hi - y_lo) * i / 4;
    text(fmt::format("{:.0f}", z), at({z, y_lo}) + cv::Point(-10, 20));
    text(fmt::format("{:.1f}", y), at({0, y}) + cv::Point(-60, 5));
  }
  text("depth z (mm)", {w / 2 - 50, h - 15});
  text("deflection y (mm)", {5, top - 15});
  text(title, {left + 160, 25}, 0.55);
  // The legend bottom left: the paths bend down to the right, away from it.
  int legend = h - bottom - 20 * static_cast<int>(curves.size()) - 5;
  for (const auto& c : curves) {
    if (c.points) {
      for (const auto& p : c.zy_mm)
        cv::circle(img, at(p), 3, c.bgr, 1, cv::LINE_AA);
    } else {
      for (std::size_t i = 1; i < c.zy_mm.size(); ++i)
        cv::line(img, at(c.zy_mm[i - 1]), at(c.zy_mm[i]), c.bgr, 2, cv::LINE_AA);
    }
    cv::line(img, {left + 15, legend - 4}, {left + 45, legend - 4}, c.bgr, 2);
    text(c.label, {left + 53, legend});
    legend += 20;
  }
  const auto png = volume::encodePngBgr(img.data, img.cols, img.rows, img.step[0]);
  if (!png || !volume::writePng(*png, path)) throw CliError{path + ": cannot write the PNG"};
}

std::vector<cv::Point2d> modelCurve(const deflection::NeedleModel& n, const deflection::Tissue& t,
                                    double length_mm) {
  auto path = deflection::simulate(n, t, length_mm, 1.0);
  if (!path) throw CliError{path.error().message};
  std::vector<cv::Point2d> out;
  for (const auto& p : *path)
    out.emplace_back(p.z_mm, p.y_mm);
  return out;
}

}  // namespace

json plotDeflection(const DeflectionArgs& args) {
  std::vector<Curve> curves;
  std::string title;
  json out = {{"png", args.png_path}};
  if (args.csv_path.empty()) {
    title = fmt::format("Tip paths, k = {:g}/mm, l = {:g} mm", args.needle.curvature_per_mm,
                        args.needle.wheelbase_mm);
    const std::vector<std::tuple<std::string, deflection::Tissue, cv::Scalar>> sets = {
        {"plain bicycle (lambda = 0)", {0.0, 0.0}, {60, 60, 60}},
        {"plastisol (0.144, 0.032)", {0.144, 0.032}, {200, 120, 0}},
        {"agar (0.49, 0.22)", {0.49, 0.22}, {0, 120, 220}},
        {"(0.8, 0.4)", {0.8, 0.4}, {160, 0, 160}},
    };
    json ends = json::array();
    for (const auto& [label, tissue, colour] : sets) {
      curves.push_back({label, modelCurve(args.needle, tissue, args.length_mm), colour});
      ends.push_back({{"label", label}, {"y_end_mm", curves.back().zy_mm.back().y}});
    }
    out["curves"] = ends;
  } else {
    const auto observed = readObservations(args.csv_path);
    deflection::FitOptions options;
    options.depth_noise_mm = args.depth_noise_mm;
    const auto fit = deflection::fitTissue(args.needle, observed, options);
    if (!fit) throw CliError{args.csv_path + ": " + fit.error().message};
    Curve seen{"observed", {}, {0, 0, 0}, true};
    double deepest = 0.0;
    for (const auto& o : observed) {
      seen.zy_mm.emplace_back(o.depth_mm, o.deflection_mm);
      deepest = std::max(deepest, o.depth_mm);
    }
    deflection::NeedleModel plain = args.needle;
    plain.curvature_per_mm = fit->bicycle_curvature_per_mm;
    // Inserted length a little beyond the deepest sample covers it (s >= z).
    const double length = deepest * 1.05 + 1.0;
    curves.push_back(seen);
    curves.push_back({fmt::format("extended fit ({:.3f}, {:.3f}): max {:.2f} mm",
                                  fit->tissue.lambda1, fit->tissue.lambda2, fit->max_error_mm),
                      modelCurve(args.needle, fit->tissue, length),
                      {0, 120, 220}});
    curves.push_back({fmt::format("plain fit (k {:.5f}): max {:.2f} mm",
                                  fit->bicycle_curvature_per_mm, fit->max_error_bicycle_mm),
                      modelCurve(plain, {}, length),
                      {60, 60, 60}});
    title = "Observed path, fitted extended and plain bicycle models";
    out["lambda1"] = fit->tissue.lambda1;
    out["lambda2"] = fit->tissue.lambda2;
  }
  savePlot(curves, title, args.png_path);
  return out;
}

json fitDeflection(const DeflectionArgs& args) {
  const auto observed = readObservations(args.csv_path);
  deflection::FitOptions options;
  options.fit_curvature = args.fit_curvature;
  options.depth_noise_mm = args.depth_noise_mm;
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
