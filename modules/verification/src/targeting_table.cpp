// The targeting error as Markdown tables for the session report (like the paper's Table V).
#include <cmath>

#include <fmt/format.h>

#include "ignav/verification/targeting_report.hpp"

namespace ignav::verification {
namespace {

constexpr const char* kNone = "—";

// 2 decimals; a value that rounds to zero prints "0.00", not "-0.00" (a sign without a size
// reads as a direction that is not there).
std::string mm(double v) {
  if (!std::isfinite(v)) return kNone;
  if (std::abs(v) < 0.005) v = 0.0;
  return fmt::format("{:.2f}", v);
}

std::string point(const Eigen::Vector3d& p) {
  return fmt::format("({}, {}, {})", mm(p.x()), mm(p.y()), mm(p.z()));
}

std::string meanSd(const Stats& s) {
  if (s.count == 0) return kNone;
  // One value has no sample SD (n - 1 = 0): say so instead of printing 0.
  return mm(s.mean) + " ± " + (s.count >= 2 ? mm(s.sd_sample) : kNone);
}

std::string predictedOf(const std::map<std::uint32_t, double>& predicted_mm, std::uint32_t id) {
  const auto it = predicted_mm.find(id);
  return it == predicted_mm.end() ? kNone : mm(it->second);
}

// Over the targets shown: the predicted errors that exist.
Stats predictedStats(const std::vector<TargetError>& errors,
                     const std::map<std::uint32_t, double>& predicted_mm) {
  std::vector<double> values;
  for (const auto& e : errors) {
    const auto it = predicted_mm.find(e.target_id);
    if (it != predicted_mm.end() && std::isfinite(it->second)) values.push_back(it->second);
  }
  return summarize(values);
}

std::string perTargetTable(const std::vector<TargetError>& errors,
                           const std::optional<std::map<std::uint32_t, double>>& predicted_mm) {
  std::string out =
      "| id | planned (mm) | actual (mm) | error vector (mm) | error (mm) | lateral (mm) | "
      "depth (mm) |";
  out += predicted_mm ? " predicted (mm) |\n" : "\n";
  out += predicted_mm ? "|---:|---|---|---|---:|---:|---:|---:|\n"
                      : "|---:|---|---|---|---:|---:|---:|\n";
  for (const auto& e : errors) {
    out += fmt::format("| {} | {} | {} | {} | {} | {} | {} |", e.target_id,
                       point(e.planned_robot_mm), point(e.actual_robot_mm), point(e.error_robot_mm),
                       mm(e.error_mm), mm(e.lateral_mm), mm(e.depth_mm));
    out += predicted_mm ? " " + predictedOf(*predicted_mm, e.target_id) + " |\n" : "\n";
  }
  return out;
}

std::string summaryTable(const std::vector<TargetError>& errors, const ErrorSummary& summary,
                         const std::optional<std::map<std::uint32_t, double>>& predicted_mm) {
  std::vector<const Stats*> columns = {&summary.error,
                                       &summary.lateral,
                                       &summary.depth,
                                       &summary.abs_axis_robot[0],
                                       &summary.abs_axis_robot[1],
                                       &summary.abs_axis_robot[2]};
  const Stats predicted = predicted_mm ? predictedStats(errors, *predicted_mm) : Stats{};
  if (predicted_mm) columns.push_back(&predicted);
  std::string out =
      "| statistic | error (mm) | lateral (mm) | depth (mm) | abs(ex) (mm) | abs(ey) (mm) | "
      "abs(ez) (mm) |";
  out += predicted_mm ? " predicted (mm) |\n" : "\n";
  out += "|---|";
  for (std::size_t i = 0; i < columns.size(); ++i)
    out += "---:|";
  out += "\n";
  auto row = [&](const char* name, auto&& cell) {
    out += fmt::format("| {} |", name);
    for (const Stats* s : columns)
      out += " " + (s->count == 0 ? std::string(kNone) : cell(*s)) + " |";
    out += "\n";
  };
  row("mean ± SD", [](const Stats& s) { return meanSd(s); });
  row("min", [](const Stats& s) { return mm(s.min); });
  row("max", [](const Stats& s) { return mm(s.max); });
  row("RMS", [](const Stats& s) { return mm(s.rms); });
  return out;
}

}  // namespace

std::string targetingTableMarkdown(
    const std::vector<TargetError>& errors, const ErrorSummary& summary,
    const std::optional<std::map<std::uint32_t, double>>& predicted_mm) {
  return perTargetTable(errors, predicted_mm) + "\n" + summaryTable(errors, summary, predicted_mm) +
         "\nRobot frame, mm; error = actual − planned; lateral: across the insertion axis (robot "
         "z), depth: along it, + when deeper than planned; SD: sample (n − 1).\n";
}

}  // namespace ignav::verification
