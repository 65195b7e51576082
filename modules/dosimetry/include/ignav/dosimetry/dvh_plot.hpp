// The cumulative dose-volume histograms as a figure (issue 42, part 5): the report's DVH plot, one
// curve per structure, planned solid and delivered dashed, the prescription marked.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/render.hpp"

namespace ignav::dosimetry {

struct DvhCurve {
  std::string name;  // "prostate (planned)"
  volume::Rgb colour;
  bool dashed = false;
  double bin_Gy = 1.0;
  std::vector<double> cumulative;  // the fraction (0-1) receiving at least k · bin_Gy
};

// Where the plot draws: dose (Gy) along x from 0 to max_Gy, volume (%) up y from 0 to 100.
struct DvhPlotLayout {
  int width_px = 900, height_px = 560;
  int left_px = 70, right_px = 210, top_px = 40, bottom_px = 50;  // margins; the legend right
  double max_Gy = 0.0;
  double x(double dose_Gy) const;   // pixel column
  double y(double fraction) const;  // pixel row
};

// The axis reaches the last dose any curve holds (at most three prescriptions), rounded up to
// 50 Gy. Errors (bad_plot): no curves, a bin not positive, a fraction outside 0-1 or not finite,
// a prescription not positive.
Expected<DvhPlotLayout> dvhPlotLayout(const std::vector<DvhCurve>& curves, double prescription_Gy);
// The figure as PNG: axes with ticks in Gy and %, a grey line at the prescription, each curve
// a 2-pixel polyline in its colour, the legend.
Expected<std::vector<std::uint8_t>> dvhPlotPng(const std::vector<DvhCurve>& curves,
                                               double prescription_Gy);

}  // namespace ignav::dosimetry
