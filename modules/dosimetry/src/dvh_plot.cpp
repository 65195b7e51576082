// The DVH figure (dvh_plot.hpp). OpenCV's core and imgproc draw it; volume::encodePngBgr writes
// the PNG (as the targeting figure does).
#include "ignav/dosimetry/dvh_plot.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace ignav::dosimetry {

double DvhPlotLayout::x(double dose_Gy) const {
  return left_px + (width_px - left_px - right_px) * dose_Gy / max_Gy;
}

double DvhPlotLayout::y(double fraction) const {
  return height_px - bottom_px - (height_px - top_px - bottom_px) * fraction;
}

Expected<DvhPlotLayout> dvhPlotLayout(const std::vector<DvhCurve>& curves, double prescription_Gy) {
  auto bad = [](const std::string& why) {
    return makeError(ErrorCode::kInvalidArgument, "DVH plot: " + why, "bad_plot");
  };
  if (curves.empty()) return bad("no curves");
  if (!(prescription_Gy > 0.0) || !std::isfinite(prescription_Gy))
    return bad(fmt::format("a prescription of {} Gy", prescription_Gy));
  double last_Gy = prescription_Gy;
  for (const auto& c : curves) {
    if (!(c.bin_Gy > 0.0) || !std::isfinite(c.bin_Gy))
      return bad(fmt::format("'{}': a bin of {} Gy", c.name, c.bin_Gy));
    for (const double f : c.cumulative)
      if (!(f >= 0.0 && f <= 1.0)) return bad(fmt::format("'{}': a fraction of {}", c.name, f));
    last_Gy = std::max(last_Gy, c.bin_Gy * static_cast<double>(c.cumulative.size()));
  }
  DvhPlotLayout layout;
  layout.max_Gy = 50.0 * std::ceil(std::min(last_Gy, 3.0 * prescription_Gy) / 50.0);
  return layout;
}

Expected<std::vector<std::uint8_t>> dvhPlotPng(const std::vector<DvhCurve>& curves,
                                               double prescription_Gy) {
  auto layout = dvhPlotLayout(curves, prescription_Gy);
  if (!layout) return layout.error();
  const DvhPlotLayout& l = *layout;
  cv::Mat canvas(l.height_px, l.width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  auto at = [&](double dose, double fraction) {
    return cv::Point(static_cast<int>(std::lround(l.x(dose))),
                     static_cast<int>(std::lround(l.y(fraction))));
  };
  auto text = [&](const std::string& s, cv::Point p, double scale = 0.45) {
    cv::putText(canvas, s, p, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  };
  const cv::Scalar grid(225, 225, 225), axis(0, 0, 0);
  const double step_Gy = l.max_Gy <= 200.0 ? 25.0 : 50.0;
  for (double d = 0.0; d <= l.max_Gy + 1e-9; d += step_Gy) {
    cv::line(canvas, at(d, 0.0), at(d, 1.0), grid, 1);
    text(fmt::format("{:g}", d), at(d, 0.0) + cv::Point(-10, 18));
  }
  for (int percent = 0; percent <= 100; percent += 20) {
    cv::line(canvas, at(0.0, percent / 100.0), at(l.max_Gy, percent / 100.0), grid, 1);
    text(fmt::format("{}", percent), at(0.0, percent / 100.0) + cv::Point(-32, 5));
  }
  cv::rectangle(canvas, at(0.0, 1.0), at(l.max_Gy, 0.0), axis, 1);
  text("dose (Gy)", at(l.max_Gy / 2.0, 0.0) + cv::Point(-30, 40), 0.5);
  text("volume (%)", cv::Point(8, l.top_px - 14), 0.5);
  cv::line(canvas, at(prescription_Gy, 0.0), at(prescription_Gy, 1.0), cv::Scalar(130, 130, 130),
           1);
  text(fmt::format("Rx {:g} Gy", prescription_Gy), at(prescription_Gy, 1.0) + cv::Point(4, -6));

  for (std::size_t n = 0; n < curves.size(); ++n) {
    const auto& c = curves[n];
    const cv::Scalar colour(c.colour.b, c.colour.g, c.colour.r);
    std::vector<cv::Point> points;
    for (std::size_t k = 0; k < c.cumulative.size(); ++k) {
      const double d = c.bin_Gy * static_cast<double>(k);
      if (d > l.max_Gy) break;
      points.push_back(at(d, c.cumulative[k]));
    }
    if (c.dashed) {  // every other 6-pixel stretch of the polyline
      double run = 0.0;
      for (std::size_t k = 1; k < points.size(); ++k) {
        const double length = cv::norm(points[k] - points[k - 1]);
        if (std::fmod(run, 12.0) < 6.0) cv::line(canvas, points[k - 1], points[k], colour, 2);
        run += length;
      }
    } else {
      cv::polylines(canvas, points, false, colour, 2, cv::LINE_8);
    }
    const cv::Point key(l.width_px - l.right_px + 16, l.top_px + 10 + 22 * static_cast<int>(n));
    for (int x = 0; x < 26; x += c.dashed ? 12 : 26)  // dashed as its curve
      cv::line(canvas, key + cv::Point(x, 0),
               key + cv::Point(std::min(26, x + (c.dashed ? 6 : 26)), 0), colour, 2);
    text(c.name, key + cv::Point(32, 5), 0.42);
  }
  return volume::encodePngBgr(canvas.data, canvas.cols, canvas.rows, canvas.step[0]);
}

}  // namespace ignav::dosimetry
