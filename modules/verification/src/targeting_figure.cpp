// Planned vs actual targets in the feasible volume (like the paper's Figs. 14-15), drawn with
// OpenCV's core and imgproc only (imgcodecs links GDAL; volume::encodePngBgr writes the PNG).
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "ignav/verification/targeting_report.hpp"
#include "ignav/volume/render.hpp"

namespace ignav::verification {
namespace {

// Room around the plot areas: the vertical tick labels at the left of each panel, two title
// lines and the panel titles above, the horizontal tick labels and axis names below, a legend.
constexpr int kLeftMargin_px = 64;
constexpr int kRightMargin_px = 16;
constexpr int kTitle_px = 84;
constexpr int kBelow_px = 46;
constexpr int kLegend_px = 34;
constexpr double kPadFraction = 0.08;  // the content never touches the frame
constexpr double kMinSpan_mm = 10.0;   // one target alone is not drawn at a microscope's scale
// Far enough outside a plot area that clipped lines end off it, small enough for int pixels.
constexpr double kFarOff_px = 1e5;
constexpr double kMaxCoordinate_mm = 1e9;

// BGR. Blue and red are told apart in the tests by their dominant channel.
const cv::Scalar kPlanned(200, 70, 0);
const cv::Scalar kActual(0, 0, 220);
const cv::Scalar kErrorLine(150, 150, 150);
const cv::Scalar kFeasibleFill(170, 225, 170);
const cv::Scalar kFeasibleEdge(70, 150, 70);
const cv::Scalar kGrid(232, 232, 232);
const cv::Scalar kInk(30, 30, 30);
const cv::Scalar kWhite(255, 255, 255);
constexpr double kFeasibleOpacity = 0.55;

constexpr const char* kAxisName[3] = {"x", "y", "z"};
constexpr int kPanelAxes[3][2] = {{0, 1}, {0, 2}, {1, 2}};
constexpr const char* kPanelTitle[3] = {"top view (x-y)", "side view (x-z)", "side view (y-z)"};

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void add(double v) { lo = std::min(lo, v), hi = std::max(hi, v); }
  bool empty() const { return !(lo <= hi); }
};

Status checkFeasible(const FeasibleVolume& f) {
  auto bad = [](const std::string& why) {
    return makeError(ErrorCode::kInvalidArgument, "feasible volume: " + why, "bad_feasible_volume");
  };
  if (f.radius_mm.size() != f.top_z_mm.size()) {
    return bad(fmt::format("{} radii but {} depths", f.radius_mm.size(), f.top_z_mm.size()));
  }
  if (f.radius_mm.size() < 2) return bad("fewer than 2 samples");
  if (!std::isfinite(f.cannula_travel_mm) || f.cannula_travel_mm < 0.0) {
    return bad(fmt::format("cannula_travel_mm = {} is not a length", f.cannula_travel_mm));
  }
  for (std::size_t i = 0; i < f.radius_mm.size(); ++i) {
    if (!std::isfinite(f.radius_mm[i]) || !std::isfinite(f.top_z_mm[i]) || f.radius_mm[i] < 0.0) {
      return bad(
          fmt::format("sample {} (r {}, z {}) is not a point", i, f.radius_mm[i], f.top_z_mm[i]));
    }
    if (i > 0 && !(f.radius_mm[i] > f.radius_mm[i - 1])) {
      return bad(fmt::format("radius_mm[{}] = {} does not increase", i, f.radius_mm[i]));
    }
  }
  return Ok{};
}

Status checkInputs(const std::vector<TargetError>& errors,
                   const std::optional<FeasibleVolume>& feasible, const FigureOptions& options) {
  if (!(options.panel_px >= 120 && options.panel_px <= 2000)) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("panel_px = {} is outside [120, 2000]", options.panel_px),
                     "bad_option");
  }
  for (const auto& e : errors) {
    if (!e.planned_robot_mm.allFinite() || !e.actual_robot_mm.allFinite()) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("target {}: planned or actual position not finite", e.target_id),
                       "non_finite");
    }
    // Past this the view's arithmetic could overflow; no point in a patient is that far.
    if (e.planned_robot_mm.cwiseAbs().maxCoeff() > kMaxCoordinate_mm ||
        e.actual_robot_mm.cwiseAbs().maxCoeff() > kMaxCoordinate_mm) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("target {}: planned or actual position beyond {:g} mm",
                                   e.target_id, kMaxCoordinate_mm),
                       "out_of_range");
    }
  }
  if (feasible) return checkFeasible(*feasible);
  return Ok{};
}

// What the view must hold, per robot axis: the feasible volume, every plan, and every seed
// within view_error_limit_mm of its plan.
std::array<Range, 3> contentBox(const std::vector<TargetError>& errors,
                                const std::optional<FeasibleVolume>& feasible,
                                const FigureOptions& options) {
  std::array<Range, 3> box;
  if (feasible) {
    const double r_max = feasible->radius_mm.back();
    const auto [lo, hi] = std::minmax_element(feasible->top_z_mm.begin(), feasible->top_z_mm.end());
    box[0].add(-r_max), box[0].add(r_max), box[1].add(-r_max), box[1].add(r_max);
    box[2].add(*lo - feasible->cannula_travel_mm), box[2].add(*hi);
  }
  for (const auto& e : errors) {
    // From the points themselves, not e.error_mm: the figure draws the points.
    const bool seed_in_view =
        (e.actual_robot_mm - e.planned_robot_mm).norm() <= options.view_error_limit_mm;
    for (Eigen::Index a = 0; a < 3; ++a) {
      box[static_cast<std::size_t>(a)].add(e.planned_robot_mm[a]);
      if (seed_in_view) box[static_cast<std::size_t>(a)].add(e.actual_robot_mm[a]);
    }
  }
  return box;
}

// A tick step of 1, 2 or 5 × 10^k giving at most `ticks` intervals over the span.
double niceStep(double span_mm, int ticks) {
  const double raw = span_mm / ticks;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * decade >= raw) return m * decade;
  }
  return 10.0 * decade;
}

std::string tickText(double v_mm, double step_mm) {
  const int digits = step_mm >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step_mm) - 1e-9));
  if (std::abs(v_mm) < 0.5 * step_mm * 1e-6) v_mm = 0.0;  // no "-0"
  return fmt::format("{:.{}f}", v_mm, digits);
}

// Pixel coordinates inside a panel's plot area (origin at its top left), not rounded.
struct Px {
  double x, y;
};

Px toPanel(const PanelAxes& p, const Eigen::Vector3d& robot_mm) {
  const double u = robot_mm[p.horizontal_axis], v = robot_mm[p.vertical_axis];
  return {(u - p.u_min_mm) / (p.u_max_mm - p.u_min_mm) * p.size_px,
          (p.v_max_mm - v) / (p.v_max_mm - p.v_min_mm) * p.size_px};
}

bool inside(const PanelAxes& p, const Px& q) {
  return q.x >= 0.0 && q.y >= 0.0 && q.x <= p.size_px && q.y <= p.size_px;
}

cv::Point toPoint(const Px& q) {
  auto c = [](double v) {
    return static_cast<int>(std::lround(std::clamp(v, -kFarOff_px, kFarOff_px)));
  };
  return {c(q.x), c(q.y)};
}

// The segment a-b clipped (Liang-Barsky) to the plot area grown by `margin`, so a seed a
// thousand metres off still gives a line that leaves the panel in its true direction.
std::optional<std::pair<Px, Px>> clipSegment(const Px& a, const Px& b, double size, double margin) {
  double t0 = 0.0, t1 = 1.0;
  const double dx = b.x - a.x, dy = b.y - a.y;
  // Inside is p·t <= q for each side (left, right, top, bottom).
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {a.x + margin, size + margin - a.x, a.y + margin, size + margin - a.y};
  for (int k = 0; k < 4; ++k) {
    if (p[k] == 0.0) {
      if (q[k] < 0.0) return std::nullopt;
      continue;
    }
    const double t = q[k] / p[k];
    if (p[k] < 0.0) {
      t0 = std::max(t0, t);
    } else {
      t1 = std::min(t1, t);
    }
  }
  if (!(t0 <= t1)) return std::nullopt;
  return std::pair{Px{a.x + t0 * dx, a.y + t0 * dy}, Px{a.x + t1 * dx, a.y + t1 * dy}};
}

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale = 0.42,
          const cv::Scalar& colour = kInk) {
  cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv::LINE_AA);
}

int textWidth(const std::string& s, double scale = 0.42) {
  int baseline = 0;
  return cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline).width;
}

// The feasible volume's projection onto a side view: at |u| = r_i it spans the z that any
// radius r >= max(r_i, r_min) reaches (the radius is sqrt(u² + w²) for some depth w into the
// view), i.e. [min top - travel, max top] over those radii: one polygon, the axis' hole hidden.
std::vector<Eigen::Vector2d> sideProjection_mm(const FeasibleVolume& f) {
  const std::size_t n = f.radius_mm.size();
  std::vector<double> hi(n), lo(n);
  for (std::size_t k = n; k-- > 0;) {
    hi[k] = k + 1 < n ? std::max(hi[k + 1], f.top_z_mm[k]) : f.top_z_mm[k];
    lo[k] = k + 1 < n ? std::min(lo[k + 1], f.top_z_mm[k]) : f.top_z_mm[k];
  }
  std::vector<Eigen::Vector2d> polygon;
  for (std::size_t k = n; k-- > 0;)
    polygon.emplace_back(-f.radius_mm[k], hi[k]);
  for (std::size_t k = 0; k < n; ++k)
    polygon.emplace_back(f.radius_mm[k], hi[k]);
  for (std::size_t k = n; k-- > 0;)
    polygon.emplace_back(f.radius_mm[k], lo[k] - f.cannula_travel_mm);
  for (std::size_t k = 0; k < n; ++k)
    polygon.emplace_back(-f.radius_mm[k], lo[k] - f.cannula_travel_mm);
  return polygon;
}

// Blends `colour` over the plot where the mask is set: the grid shows through.
void tint(cv::Mat& plot, const cv::Mat& mask, const cv::Scalar& colour, double opacity) {
  const cv::Mat fill(plot.size(), plot.type(), colour);
  cv::Mat blended;
  cv::addWeighted(fill, opacity, plot, 1.0 - opacity, 0.0, blended);
  blended.copyTo(plot, mask);
}

void drawFeasible(cv::Mat& plot, const PanelAxes& p, const FeasibleVolume& f) {
  cv::Mat mask = cv::Mat::zeros(plot.size(), CV_8U);
  if (p.vertical_axis != 2) {
    // Seen along the cannula axis the volume is the annulus r_min <= r <= r_max.
    const double px_per_mm = p.size_px / (p.u_max_mm - p.u_min_mm);
    const cv::Point centre = toPoint(toPanel(p, Eigen::Vector3d::Zero()));
    auto radius = [&](double r_mm) {
      return static_cast<int>(std::lround(std::min(r_mm * px_per_mm, kFarOff_px)));
    };
    cv::circle(mask, centre, radius(f.radius_mm.back()), 255, cv::FILLED);
    cv::circle(mask, centre, radius(f.radius_mm.front()), 0, cv::FILLED);
    tint(plot, mask, kFeasibleFill, kFeasibleOpacity);
    cv::circle(plot, centre, radius(f.radius_mm.back()), kFeasibleEdge, 1, cv::LINE_AA);
    cv::circle(plot, centre, radius(f.radius_mm.front()), kFeasibleEdge, 1, cv::LINE_AA);
    return;
  }
  std::vector<cv::Point> polygon;
  for (const auto& uz : sideProjection_mm(f)) {
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    q[p.horizontal_axis] = uz.x();
    q.z() = uz.y();
    polygon.push_back(toPoint(toPanel(p, q)));
  }
  const std::vector<std::vector<cv::Point>> polygons{polygon};
  cv::fillPoly(mask, polygons, 255);
  tint(plot, mask, kFeasibleFill, kFeasibleOpacity);
  cv::polylines(plot, polygons, true, kFeasibleEdge, 1, cv::LINE_AA);
}

// The ticks on [lo, hi] are k · step for k from ticksFrom to ticksTo (a hair of slack: a tick on
// the frame is drawn whatever the rounding).
long ticksFrom(double lo_mm, double step_mm) {
  return static_cast<long>(std::ceil(lo_mm / step_mm - 1e-9));
}
long ticksTo(double hi_mm, double step_mm) {
  return static_cast<long>(std::floor(hi_mm / step_mm + 1e-9));
}

// Grid lines at every tick, tick marks and their values outside the plot area, the axis names.
void drawAxes(cv::Mat& canvas, const PanelAxes& p, double step_mm) {
  cv::Mat plot = canvas(cv::Rect(p.left_px, p.top_px, p.size_px + 1, p.size_px + 1));
  const int bottom = p.top_px + p.size_px;
  int next_free_x = 0;
  for (long k = ticksFrom(p.u_min_mm, step_mm); k <= ticksTo(p.u_max_mm, step_mm); ++k) {
    const double u = static_cast<double>(k) * step_mm;
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    q[p.horizontal_axis] = u;
    const int x = toPoint(toPanel(p, q)).x;
    cv::line(plot, {x, 0}, {x, p.size_px}, kGrid, 1);
    cv::line(canvas, {p.left_px + x, bottom}, {p.left_px + x, bottom + 4}, kInk, 1);
    const std::string label = tickText(u, step_mm);
    const int label_left = p.left_px + x - textWidth(label) / 2;
    if (label_left < next_free_x) continue;  // wide values (a far-off view) would overlap
    text(canvas, label, {label_left, bottom + 18});
    next_free_x = label_left + textWidth(label) + 6;
  }
  for (long k = ticksFrom(p.v_min_mm, step_mm); k <= ticksTo(p.v_max_mm, step_mm); ++k) {
    const double v = static_cast<double>(k) * step_mm;
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    q[p.vertical_axis] = v;
    const int y = toPoint(toPanel(p, q)).y;
    cv::line(plot, {0, y}, {p.size_px, y}, kGrid, 1);
    cv::line(canvas, {p.left_px - 4, p.top_px + y}, {p.left_px, p.top_px + y}, kInk, 1);
    const std::string label = tickText(v, step_mm);
    text(canvas, label, {p.left_px - 7 - textWidth(label), p.top_px + y + 4});
  }
  const std::string u_name = std::string(kAxisName[p.horizontal_axis]) + " (mm)";
  text(canvas, u_name, {p.left_px + (p.size_px - textWidth(u_name)) / 2, bottom + 38}, 0.45);
  text(canvas, std::string(kAxisName[p.vertical_axis]) + " (mm)",
       {p.left_px - kLeftMargin_px + 6, p.top_px - 20}, 0.45);
}

void drawTargets(cv::Mat& plot, const PanelAxes& p, const std::vector<TargetError>& errors,
                 bool labels) {
  for (const auto& e : errors) {
    const auto clipped =
        clipSegment(toPanel(p, e.planned_robot_mm), toPanel(p, e.actual_robot_mm), p.size_px, 20.0);
    if (clipped) {
      cv::line(plot, toPoint(clipped->first), toPoint(clipped->second), kErrorLine, 1, cv::LINE_AA);
    }
  }
  for (const auto& e : errors)
    cv::circle(plot, toPoint(toPanel(p, e.planned_robot_mm)), 5, kPlanned, 2, cv::LINE_8);
  for (const auto& e : errors) {
    const Px actual = toPanel(p, e.actual_robot_mm);
    if (inside(p, actual)) {
      cv::drawMarker(plot, toPoint(actual), kActual, cv::MARKER_CROSS, 11, 2, cv::LINE_8);
    }
  }
  if (!labels) return;
  for (const auto& e : errors) {
    const cv::Point c = toPoint(toPanel(p, e.planned_robot_mm));
    text(plot, std::to_string(e.target_id), {c.x + 7, c.y - 7}, 0.38);
  }
}

// Seeds that some panel cannot show (farther than view_error_limit_mm from a plan at the edge).
std::size_t seedsOffView(const FigureLayout& layout, const std::vector<TargetError>& errors) {
  return static_cast<std::size_t>(
      std::count_if(errors.begin(), errors.end(), [&](const TargetError& e) {
        return std::any_of(layout.panels.begin(), layout.panels.end(), [&](const PanelAxes& p) {
          return !inside(p, toPanel(p, e.actual_robot_mm));
        });
      }));
}

std::string summaryLine(const ErrorSummary& summary) {
  const Stats& s = summary.error;
  if (s.count == 0) return "no targets measured";
  if (s.count == 1) return fmt::format("1 target: error {:.2f} mm", s.mean);
  // Hershey fonts are ASCII: "+/-" for the plus-minus sign.
  return fmt::format(
      "{} targets: error mean {:.2f} +/- {:.2f} mm (sample SD), max {:.2f}, min {:.2f}, RMS "
      "{:.2f} mm",
      s.count, s.mean, s.sd_sample, s.max, s.min, s.rms);
}

void drawLegend(cv::Mat& canvas, int y, bool feasible, bool labelled, std::size_t seeds_off_view) {
  int x = kLeftMargin_px;
  cv::circle(canvas, {x, y - 4}, 5, kPlanned, 2, cv::LINE_8);
  text(canvas, "planned target", {x + 12, y});
  x += 130;
  cv::drawMarker(canvas, {x, y - 4}, kActual, cv::MARKER_CROSS, 11, 2, cv::LINE_8);
  text(canvas, "actual seed", {x + 12, y});
  x += 110;
  cv::line(canvas, {x - 6, y - 4}, {x + 14, y - 4}, kErrorLine, 1, cv::LINE_AA);
  text(canvas, "planned to actual", {x + 20, y});
  x += 160;
  if (feasible) {
    cv::rectangle(canvas, {x - 6, y - 10}, {x + 8, y + 2}, kFeasibleFill, cv::FILLED);
    cv::rectangle(canvas, {x - 6, y - 10}, {x + 8, y + 2}, kFeasibleEdge, 1);
    text(canvas, "feasible volume (projection)", {x + 14, y});
    x += 240;
  }
  std::string note;
  if (seeds_off_view > 0) note = fmt::format("{} seed(s) off the view", seeds_off_view);
  if (!labelled) note += std::string(note.empty() ? "" : "; ") + "ids in the table";
  if (!note.empty()) text(canvas, note, {x, y});
}

}  // namespace

FeasibleVolume feasibleVolume(const kinematics::Kinematics& kinematics, int samples) {
  const int n = std::max(samples, 2);
  const double travel_mm = kinematics.instrument().stylet_travel_mm;
  FeasibleVolume f;
  f.cannula_travel_mm = kinematics.instrument().cannula_travel_mm;
  // At θc = 0 and z_c = 0 the tip lies in the yz-plane at its radius and its shallowest depth;
  // the radius grows strictly with z_s (checked by Kinematics::create).
  for (int i = 0; i < n; ++i) {
    const double z_s = travel_mm * i / (n - 1);
    const Eigen::Vector3d tip = kinematics.forward({0.0, 0.0, z_s}).tip_mm;
    f.radius_mm.push_back(std::hypot(tip.x(), tip.y()));
    f.top_z_mm.push_back(tip.z());
  }
  return f;
}

Expected<FigureLayout> targetingFigureLayout(const std::vector<TargetError>& errors,
                                             const std::optional<FeasibleVolume>& feasible,
                                             const FigureOptions& options) {
  if (auto ok = checkInputs(errors, feasible, options); !ok) return ok.error();
  const std::array<Range, 3> box = contentBox(errors, feasible, options);
  // One span for every axis: the same mm per pixel everywhere, so shapes and distances compare
  // across the panels.
  double span_mm = kMinSpan_mm;
  for (const auto& r : box) {
    if (!r.empty()) span_mm = std::max(span_mm, (r.hi - r.lo) * (1.0 + 2.0 * kPadFraction));
  }
  std::array<double, 3> centre_mm{};
  for (std::size_t a = 0; a < 3; ++a)
    centre_mm[a] = box[a].empty() ? 0.0 : 0.5 * (box[a].lo + box[a].hi);
  FigureLayout layout;
  const int size = options.panel_px;
  layout.width_px = 3 * (kLeftMargin_px + size) + kRightMargin_px;
  layout.height_px = kTitle_px + size + kBelow_px + kLegend_px;
  for (std::size_t i = 0; i < 3; ++i) {
    PanelAxes& p = layout.panels[i];
    p.horizontal_axis = kPanelAxes[i][0];
    p.vertical_axis = kPanelAxes[i][1];
    p.left_px = kLeftMargin_px + static_cast<int>(i) * (kLeftMargin_px + size);
    p.top_px = kTitle_px;
    p.size_px = size;
    const double u_c = centre_mm[static_cast<std::size_t>(p.horizontal_axis)];
    const double v_c = centre_mm[static_cast<std::size_t>(p.vertical_axis)];
    p.u_min_mm = u_c - 0.5 * span_mm, p.u_max_mm = u_c + 0.5 * span_mm;
    p.v_min_mm = v_c - 0.5 * span_mm, p.v_max_mm = v_c + 0.5 * span_mm;
  }
  return layout;
}

Expected<std::vector<std::uint8_t>> targetingFigurePng(
    const std::vector<TargetError>& errors, const ErrorSummary& summary,
    const std::optional<FeasibleVolume>& feasible, const FigureOptions& options) {
  auto layout = targetingFigureLayout(errors, feasible, options);
  if (!layout) return layout.error();
  cv::Mat canvas(layout->height_px, layout->width_px, CV_8UC3, kWhite);
  text(canvas, options.title, {kLeftMargin_px, 24}, 0.6);
  text(canvas, summaryLine(summary), {kLeftMargin_px, 48}, 0.48);
  const bool labels = static_cast<int>(errors.size()) <= options.max_labelled_targets;
  for (std::size_t i = 0; i < 3; ++i) {
    const PanelAxes& p = layout->panels[i];
    const double step_mm = niceStep(p.u_max_mm - p.u_min_mm, 8);
    drawAxes(canvas, p, step_mm);
    cv::Mat plot = canvas(cv::Rect(p.left_px, p.top_px, p.size_px + 1, p.size_px + 1));
    if (feasible) drawFeasible(plot, p, *feasible);
    drawTargets(plot, p, errors, labels);
    cv::rectangle(plot, {0, 0}, {p.size_px, p.size_px}, kInk, 1);
    text(canvas, kPanelTitle[i],
         {p.left_px + (p.size_px - textWidth(kPanelTitle[i], 0.5)) / 2, p.top_px - 10}, 0.5);
  }
  drawLegend(canvas, layout->height_px - 12, feasible.has_value(), labels,
             seedsOffView(*layout, errors));
  return volume::encodePngBgr(canvas.data, canvas.cols, canvas.rows, canvas.step[0]);
}

}  // namespace ignav::verification
