// The targeting error as the session report shows it (issue 23): a Markdown table like the
// paper's Table V, and a figure like its Figs. 14-15 (planned vs actual in the feasible volume).
// Pure: values in, text or PNG bytes out; the caller writes the files.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/kinematics/solver.hpp"
#include "ignav/verification/targeting_error.hpp"

namespace ignav::verification {

// Two tables, robot frame, mm, 2 decimals, "—" where there is no number:
// per target `id | planned | actual | error vector | error | lateral | depth [| predicted]`
// (depth + when deeper than planned), then the summary `statistic | error | lateral | depth |
// abs(ex) | abs(ey) | abs(ez) [| predicted]` with rows `mean ± SD` (sample SD), `min`, `max`,
// `RMS`. `predicted_mm`: the model's predicted landing error per target id (a NaN or an absent
// id shows "—"); without it there is no predicted column. A line under the tables says what the
// columns mean.
std::string targetingTableMarkdown(
    const std::vector<TargetError>& errors, const ErrorSummary& summary,
    const std::optional<std::map<std::uint32_t, double>>& predicted_mm = std::nullopt);

// The feasible volume, a solid of revolution about the cannula axis (robot z): at every tip
// radius r in [radius_mm.front(), radius_mm.back()] the tip reaches z in
// [top_z_mm(r) - cannula_travel_mm, top_z_mm(r)] (docs/KINEMATICS.md, "Feasible volume").
struct FeasibleVolume {
  std::vector<double> radius_mm;  // increasing, from r_min to r_max
  std::vector<double> top_z_mm;   // the shallowest tip at that radius (z_c = 0)
  double cannula_travel_mm = 0.0;
};

// The instrument's, at `samples` stylet deployments (at least 2, evenly from 0 to its travel):
// the radii run from r_min to r_max.
FeasibleVolume feasibleVolume(const kinematics::Kinematics& kinematics, int samples = 64);

struct FigureOptions {
  int panel_px = 360;  // each panel's plot area is a square this size
  std::string title = "Targeting error: planned vs actual (robot frame, mm)";
  // An actual seed farther than this from its plan does not widen the view (one wild seed
  // would shrink every other to a dot): off the view, its line is clipped at the panel's edge
  // and the legend counts it.
  double view_error_limit_mm = 15.0;
  int max_labelled_targets = 40;  // beyond, ids would hide the points: the table has them
};

// One panel's plot area and the mm it spans (the same mm per pixel on both of its axes and in
// every panel): robot axis u runs right from u_min_mm at left_px, robot axis v runs up from
// v_min_mm at top_px + size_px.
struct PanelAxes {
  int horizontal_axis = 0;  // 0 x, 1 y, 2 z (robot frame)
  int vertical_axis = 1;
  int left_px = 0, top_px = 0, size_px = 0;
  double u_min_mm = 0.0, u_max_mm = 0.0, v_min_mm = 0.0, v_max_mm = 0.0;
};

struct FigureLayout {
  int width_px = 0, height_px = 0;
  std::array<PanelAxes, 3> panels;  // top view x-y, side view x-z, side view y-z
};

// Where targetingFigurePng draws. Errors: a non-finite point or one beyond 1e9 mm (naming the
// target: non_finite, out_of_range), a feasible volume with mismatched, too few, non-increasing
// or non-finite samples (bad_feasible_volume), panel_px outside [120, 2000] (bad_option).
Expected<FigureLayout> targetingFigureLayout(const std::vector<TargetError>& errors,
                                             const std::optional<FeasibleVolume>& feasible,
                                             const FigureOptions& options = {});

// Three panels (layout above) with ticks and labels in mm: the feasible volume's projection
// shaded green, each planned target a blue circle, each actual seed a red cross, a grey line
// from one to the other, the ids; a legend, and the title with mean ± SD (sample), max, min and
// RMS of |error|. Errors as targetingFigureLayout.
Expected<std::vector<std::uint8_t>> targetingFigurePng(
    const std::vector<TargetError>& errors, const ErrorSummary& summary,
    const std::optional<FeasibleVolume>& feasible, const FigureOptions& options = {});

}  // namespace ignav::verification
