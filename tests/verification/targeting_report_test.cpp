// The session report's targeting artifacts (issue 23): the Markdown table read back against
// closed-form statistics, and the figure decoded by OpenCV's own PNG reader with its points found
// where the axis mapping it declares puts them; the feasible volume checked against the inverse
// kinematics.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <limits>
#include <sstream>

#include "ignav/verification/targeting_report.hpp"

namespace ignav::verification {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A measured target with the error vector given (robot frame), the rest derived as
// targetError derives it (identity registration).
TargetError measured(std::uint32_t id, const Eigen::Vector3d& planned,
                     const Eigen::Vector3d& error) {
  auto e = targetError({id, planned}, planned + error, Eigen::Matrix4d::Identity());
  EXPECT_TRUE(e.ok());
  return *e;
}

// |error| = 1, 2, 3, 4 mm: mean 2.5, sample SD √(5/3) = 1.29099, RMS √7.5 = 2.73861.
// Lateral 1, 2, 0, 0; depth (+ deeper = -ez) 0, 0, 3, -4; |ex| 1, 0, 0, 0; |ez| 0, 0, 3, 4.
std::vector<TargetError> oneTwoThreeFour() {
  return {measured(1, {10.0, 5.0, -180.0}, {1.0, 0.0, 0.0}),
          measured(2, {-8.0, 6.0, -175.0}, {0.0, 2.0, 0.0}),
          measured(3, {4.0, -12.0, -190.0}, {0.0, 0.0, -3.0}),
          measured(4, {-3.0, -9.0, -170.0}, {0.0, 0.0, 4.0})};
}

using Row = std::vector<std::string>;

// The Markdown tables' rows, cells trimmed, separator rows left out.
std::vector<Row> tableRows(const std::string& markdown) {
  std::vector<Row> rows;
  std::istringstream in(markdown);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line.front() != '|' || line.find("---") != std::string::npos) continue;
    Row row;
    std::size_t start = 1;
    for (std::size_t bar; (bar = line.find('|', start)) != std::string::npos; start = bar + 1) {
      std::string cell = line.substr(start, bar - start);
      cell.erase(0, cell.find_first_not_of(' '));
      cell.erase(cell.find_last_not_of(' ') + 1);
      row.push_back(cell);
    }
    rows.push_back(row);
  }
  return rows;
}

const Row& rowNamed(const std::vector<Row>& rows, const std::string& first) {
  for (const auto& r : rows) {
    if (!r.empty() && r.front() == first) return r;
  }
  static const Row none;
  ADD_FAILURE() << "no row " << first;
  return none;
}

// "(a, b, c)" -> the three numbers.
Eigen::Vector3d triple(const std::string& cell) {
  Eigen::Vector3d v;
  char open = 0, c1 = 0, c2 = 0;
  std::istringstream(cell) >> open >> v.x() >> c1 >> v.y() >> c2 >> v.z();
  return v;
}

// "m ± s" -> m and s (s NaN for "—").
std::pair<double, double> meanSd(const std::string& cell) {
  const auto pm = cell.find("±");
  EXPECT_NE(pm, std::string::npos) << cell;
  const double mean = std::stod(cell.substr(0, pm));
  const std::string sd = cell.substr(pm + std::string("±").size() + 1);
  return {mean, sd == "—" ? kNaN : std::stod(sd)};
}

TEST(TargetingTable, PerTargetRowsReadBackAsTheInputs) {
  const auto errors = oneTwoThreeFour();
  const auto rows = tableRows(targetingTableMarkdown(errors, summarizeErrors(errors)));
  const Row& header = rows.front();
  ASSERT_EQ(header.size(), 7u);  // no predicted column without predictions
  EXPECT_EQ(header[0], "id");
  for (const auto& e : errors) {
    const Row& r = rowNamed(rows, std::to_string(e.target_id));
    ASSERT_EQ(r.size(), 7u);
    EXPECT_LT((triple(r[1]) - e.planned_robot_mm).norm(), 1e-9) << r[1];
    EXPECT_LT((triple(r[2]) - e.actual_robot_mm).norm(), 1e-9) << r[2];
    EXPECT_LT((triple(r[3]) - e.error_robot_mm).norm(), 1e-9) << r[3];
  }
  const Row& third = rowNamed(rows, "3");
  EXPECT_EQ(third[4], "3.00");  // |error|
  EXPECT_EQ(third[5], "0.00");  // lateral
  EXPECT_EQ(third[6], "3.00");  // 3 mm deeper than planned
  EXPECT_EQ(rowNamed(rows, "4")[6], "-4.00");
  EXPECT_EQ(rowNamed(rows, "2")[5], "2.00");
}

TEST(TargetingTable, SummaryRowsAreTheClosedFormStatistics) {
  const auto errors = oneTwoThreeFour();
  const auto rows = tableRows(targetingTableMarkdown(errors, summarizeErrors(errors)));
  const Row& mean = rowNamed(rows, "mean ± SD");
  ASSERT_EQ(mean.size(), 7u);
  // statistic | error | lateral | depth | abs(ex) | abs(ey) | abs(ez)
  const auto [error_mean, error_sd] = meanSd(mean[1]);
  EXPECT_NEAR(error_mean, 2.5, 0.005);
  EXPECT_NEAR(error_sd, 1.29099, 0.005);
  EXPECT_NEAR(std::stod(rowNamed(rows, "RMS")[1]), 2.73861, 0.005);
  EXPECT_EQ(rowNamed(rows, "min")[1], "1.00");
  EXPECT_EQ(rowNamed(rows, "max")[1], "4.00");
  // Lateral 1, 2, 0, 0: mean 0.75, SD √(2.75/3) = 0.957.
  EXPECT_EQ(mean[2], "0.75 ± 0.96");
  // Depth signed 0, 0, 3, -4: the bias -0.25, min -4, max 3, RMS √(25/4) = 2.5.
  EXPECT_NEAR(meanSd(mean[3]).first, -0.25, 1e-9);
  EXPECT_EQ(rowNamed(rows, "min")[3], "-4.00");
  EXPECT_EQ(rowNamed(rows, "max")[3], "3.00");
  EXPECT_EQ(rowNamed(rows, "RMS")[3], "2.50");
  // Per axis |e|: x 1, 0, 0, 0 (mean 0.25); y 0, 2, 0, 0 (0.5); z 0, 0, 3, 4 (1.75).
  EXPECT_NEAR(meanSd(mean[4]).first, 0.25, 1e-9);
  EXPECT_NEAR(meanSd(mean[5]).first, 0.50, 1e-9);
  EXPECT_NEAR(meanSd(mean[6]).first, 1.75, 1e-9);
  EXPECT_EQ(rowNamed(rows, "max")[6], "4.00");
}

TEST(TargetingTable, PredictedColumnShowsADashForNaNOrNoPrediction) {
  const auto errors = oneTwoThreeFour();
  const std::map<std::uint32_t, double> predicted = {{1, 0.5}, {2, kNaN}};  // none for 3, 4
  const auto rows = tableRows(targetingTableMarkdown(errors, summarizeErrors(errors), predicted));
  ASSERT_EQ(rows.front().size(), 8u);
  EXPECT_EQ(rows.front()[7], "predicted (mm)");
  EXPECT_EQ(rowNamed(rows, "1")[7], "0.50");
  EXPECT_EQ(rowNamed(rows, "2")[7], "—");
  EXPECT_EQ(rowNamed(rows, "3")[7], "—");
  // Over the one prediction there is: its value, and no sample SD.
  EXPECT_EQ(rowNamed(rows, "mean ± SD")[7], "0.50 ± —");
  EXPECT_EQ(rowNamed(rows, "max")[7], "0.50");
}

TEST(TargetingTable, NoTargetsGivesHeadersAndDashes) {
  const auto rows = tableRows(targetingTableMarkdown({}, summarizeErrors({})));
  ASSERT_EQ(rows.size(), 6u);  // two headers, four statistics
  for (const char* stat : {"mean ± SD", "min", "max", "RMS"}) {
    const Row& r = rowNamed(rows, stat);
    for (std::size_t i = 1; i < r.size(); ++i)
      EXPECT_EQ(r[i], "—") << stat;
  }
}

TEST(TargetingTable, AnErrorThatRoundsToZeroHasNoSign) {
  const std::vector<TargetError> errors = {measured(9, {1.0, 2.0, -150.0}, {-0.001, 0.0, 0.0})};
  const std::string md = targetingTableMarkdown(errors, summarizeErrors(errors));
  EXPECT_EQ(md.find("-0.00"), std::string::npos) << md;
}

// The paper's instrument (Instrument's defaults).
const kinematics::Kinematics& paperKinematics() {
  static const kinematics::Kinematics k = *kinematics::Kinematics::create({});
  return k;
}

TEST(FeasibleVolume, ItsTopIsWhereTheInverseNeedsNoCannulaTravel) {
  const auto& k = paperKinematics();
  const FeasibleVolume f = feasibleVolume(k, 16);
  ASSERT_EQ(f.radius_mm.size(), 16u);
  EXPECT_NEAR(f.radius_mm.front(), k.workspace().r_min_mm, 1e-9);
  EXPECT_NEAR(f.radius_mm.back(), k.workspace().r_max_mm, 1e-9);
  EXPECT_DOUBLE_EQ(f.cannula_travel_mm, k.instrument().cannula_travel_mm);
  for (std::size_t i = 0; i < f.radius_mm.size(); ++i) {
    // At a quarter turn, to check the volume is one of revolution.
    const Eigen::Vector3d top(-f.radius_mm[i], 0.0, f.top_z_mm[i]);
    const auto at_top = k.inverse(top);
    ASSERT_TRUE(at_top.ok());
    EXPECT_TRUE(at_top->reachable()) << i;
    EXPECT_NEAR(at_top->joints.z_c_mm, 0.0, 1e-6) << i;
    EXPECT_EQ(k.inverse(top + Eigen::Vector3d(0, 0, 0.5))->reach, kinematics::Reach::kTooShallow);
    const Eigen::Vector3d bottom = top - Eigen::Vector3d(0, 0, f.cannula_travel_mm);
    EXPECT_TRUE(k.inverse(bottom)->reachable()) << i;
    EXPECT_EQ(k.inverse(bottom - Eigen::Vector3d(0, 0, 0.5))->reach, kinematics::Reach::kTooDeep);
  }
}

cv::Mat decode(const std::vector<std::uint8_t>& png) {
  return cv::imdecode(
      cv::Mat(1, static_cast<int>(png.size()), CV_8UC1, const_cast<std::uint8_t*>(png.data())),
      cv::IMREAD_COLOR);
}

// Where a robot-frame point falls in a panel, from the panel's declared axes alone: u grows to
// the right from u_min at the plot's left edge, v grows upwards from v_min at its bottom edge.
cv::Point2d pixelOf(const PanelAxes& p, const Eigen::Vector3d& robot_mm) {
  const double u = robot_mm[p.horizontal_axis], v = robot_mm[p.vertical_axis];
  return {p.left_px + (u - p.u_min_mm) * p.size_px / (p.u_max_mm - p.u_min_mm),
          p.top_px + (p.v_max_mm - v) * p.size_px / (p.v_max_mm - p.v_min_mm)};
}

bool blue(const cv::Vec3b& bgr) {
  return bgr[0] > 150 && bgr[1] < 120 && bgr[2] < 80;
}
bool red(const cv::Vec3b& bgr) {
  return bgr[2] > 150 && bgr[1] < 80 && bgr[0] < 80;
}
bool greenTinted(const cv::Vec3b& bgr) {
  return bgr[1] > bgr[0] + 15 && bgr[1] > bgr[2] + 15;
}

// Pixels of a colour within [r_lo, r_hi] px of a point.
int countNear(const cv::Mat& img, cv::Point2d c, double r_lo, double r_hi,
              bool (*is)(const cv::Vec3b&)) {
  int n = 0;
  for (int y = static_cast<int>(c.y - r_hi) - 1; y <= static_cast<int>(c.y + r_hi) + 1; ++y) {
    for (int x = static_cast<int>(c.x - r_hi) - 1; x <= static_cast<int>(c.x + r_hi) + 1; ++x) {
      if (x < 0 || y < 0 || x >= img.cols || y >= img.rows) continue;
      const double d = std::hypot(x - c.x, y - c.y);
      if (d >= r_lo && d <= r_hi && is(img.at<cv::Vec3b>(y, x))) ++n;
    }
  }
  return n;
}

TEST(TargetingFigure, PlannedCirclesAndActualCrossesLandWhereTheAxesSay) {
  const std::vector<TargetError> errors = {measured(1, {10.0, 5.0, -180.0}, {3.0, 0.0, -4.0}),
                                           measured(2, {-8.0, -6.0, -170.0}, {0.0, 2.5, -1.5})};
  const FeasibleVolume feasible = feasibleVolume(paperKinematics());
  const auto layout = targetingFigureLayout(errors, feasible);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  const auto png = targetingFigurePng(errors, summarizeErrors(errors), feasible);
  ASSERT_TRUE(png.ok()) << png.error().message;
  const cv::Mat img = decode(*png);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, layout->width_px);
  EXPECT_EQ(img.rows, layout->height_px);
  for (const PanelAxes& p : layout->panels) {
    // The same mm per pixel on both axes: shapes are not stretched.
    EXPECT_NEAR(p.u_max_mm - p.u_min_mm, p.v_max_mm - p.v_min_mm, 1e-9);
    for (const auto& e : errors) {
      // The circle (radius 5 px, 2 px wide) around the plan; the cross's centre on the seed.
      EXPECT_GE(countNear(img, pixelOf(p, e.planned_robot_mm), 3.5, 6.5, blue), 12)
          << "target " << e.target_id << " axes " << p.horizontal_axis << p.vertical_axis;
      EXPECT_GE(countNear(img, pixelOf(p, e.actual_robot_mm), 0.0, 1.5, red), 3)
          << "target " << e.target_id << " axes " << p.horizontal_axis << p.vertical_axis;
    }
  }
  // The feasible volume: a reachable point off the grid lines and the targets is shaded in the
  // side view x-z; a point 2 mm above the shallowest reach, and the axis in the top view, are not.
  const auto& k = paperKinematics();
  const Eigen::Vector3d reachable(-13.7, 0.0, -187.3);
  ASSERT_TRUE(k.inverse(reachable)->reachable());
  EXPECT_TRUE(greenTinted(img.at<cv::Vec3b>(pixelOf(layout->panels[1], reachable))));
  const double top_mm = *std::max_element(feasible.top_z_mm.begin(), feasible.top_z_mm.end());
  const Eigen::Vector3d above(-13.7, 0.0, top_mm + 2.0);
  EXPECT_FALSE(greenTinted(img.at<cv::Vec3b>(pixelOf(layout->panels[1], above))));
  const Eigen::Vector3d on_axis(0.3, 0.3, 0.0);  // inside r_min: out of reach at any depth
  ASSERT_LT(std::hypot(on_axis.x(), on_axis.y()), feasible.radius_mm.front());
  EXPECT_FALSE(greenTinted(img.at<cv::Vec3b>(pixelOf(layout->panels[0], on_axis))));
  const Eigen::Vector3d in_annulus(-14.3, -7.7, 0.0);
  EXPECT_TRUE(greenTinted(img.at<cv::Vec3b>(pixelOf(layout->panels[0], in_annulus))));
}

TEST(TargetingFigure, NoTargetsIsAValidPng) {
  for (const bool with_volume : {false, true}) {
    const std::optional<FeasibleVolume> feasible =
        with_volume ? std::optional(feasibleVolume(paperKinematics())) : std::nullopt;
    const auto png = targetingFigurePng({}, summarizeErrors({}), feasible);
    ASSERT_TRUE(png.ok()) << png.error().message;
    const cv::Mat img = decode(*png);
    ASSERT_FALSE(img.empty());
    EXPECT_EQ(img.cols, targetingFigureLayout({}, feasible)->width_px);
    EXPECT_EQ(img.rows, targetingFigureLayout({}, feasible)->height_px);
  }
}

TEST(TargetingFigure, OneTargetWithoutAVolumeSitsInTheMiddle) {
  const std::vector<TargetError> errors = {measured(5, {2.0, 3.0, -160.0}, {0.0, 0.0, 0.0})};
  const auto layout = targetingFigureLayout(errors, std::nullopt);
  ASSERT_TRUE(layout.ok());
  const cv::Mat img = decode(*targetingFigurePng(errors, summarizeErrors(errors), std::nullopt));
  for (const PanelAxes& p : layout->panels) {
    EXPECT_NEAR(pixelOf(p, errors[0].planned_robot_mm).x, p.left_px + p.size_px / 2.0, 1e-9);
    EXPECT_NEAR(pixelOf(p, errors[0].planned_robot_mm).y, p.top_px + p.size_px / 2.0, 1e-9);
    EXPECT_GE(countNear(img, pixelOf(p, errors[0].actual_robot_mm), 0.0, 1.5, red), 3);
  }
}

TEST(TargetingFigure, AHugeErrorIsClippedAtTheEdgeNotZoomedOutTo) {
  const std::vector<TargetError> errors = {measured(1, {10.0, 5.0, -180.0}, {1.0, 0.0, 0.0}),
                                           measured(2, {-5.0, 8.0, -175.0}, {1e6, 0.0, 0.0})};
  const auto layout = targetingFigureLayout(errors, std::nullopt);
  ASSERT_TRUE(layout.ok());
  const PanelAxes& top = layout->panels[0];
  EXPECT_LT(top.u_max_mm - top.u_min_mm, 50.0);
  const auto png = targetingFigurePng(errors, summarizeErrors(errors), std::nullopt);
  ASSERT_TRUE(png.ok());
  const cv::Mat img = decode(*png);
  ASSERT_FALSE(img.empty());
  // The line from target 2 runs to the panel's right edge along its row.
  const cv::Point2d planned = pixelOf(top, errors[1].planned_robot_mm);
  const int edge_x = top.left_px + top.size_px - 3;
  bool line = false;
  for (int dy = -1; dy <= 1; ++dy) {
    const cv::Vec3b px = img.at<cv::Vec3b>(static_cast<int>(std::lround(planned.y)) + dy, edge_x);
    line = line || (px[0] < 200 && px[1] < 200 && px[2] < 200);
  }
  EXPECT_TRUE(line);
}

TEST(TargetingFigure, AHundredTargetsRender) {
  std::vector<TargetError> errors;
  for (std::uint32_t i = 0; i < 100; ++i) {
    const double a = 0.37 * i;
    errors.push_back(measured(i, {15.0 * std::cos(a), 15.0 * std::sin(a), -165.0 - 0.3 * i},
                              {std::sin(3.0 * a), std::cos(2.0 * a), -1.5 * std::sin(a)}));
  }
  const auto png =
      targetingFigurePng(errors, summarizeErrors(errors), feasibleVolume(paperKinematics()));
  ASSERT_TRUE(png.ok()) << png.error().message;
  EXPECT_FALSE(decode(*png).empty());
}

TEST(TargetingFigure, BadInputIsRefusedWithTheReason) {
  std::vector<TargetError> errors = {measured(7, {1.0, 2.0, -150.0}, {0.5, 0.0, 0.0})};
  errors[0].actual_robot_mm.x() = kNaN;
  const auto non_finite = targetingFigurePng(errors, summarizeErrors({}), std::nullopt);
  ASSERT_FALSE(non_finite.ok());
  EXPECT_EQ(non_finite.error().reason, "non_finite");
  EXPECT_NE(non_finite.error().message.find("target 7"), std::string::npos);

  errors[0].actual_robot_mm.x() = 1e12;  // a million kilometres: refused, not overflowed
  EXPECT_EQ(targetingFigureLayout(errors, std::nullopt).error().reason, "out_of_range");

  FeasibleVolume backwards = feasibleVolume(paperKinematics(), 4);
  std::swap(backwards.radius_mm[1], backwards.radius_mm[2]);
  const auto bad_volume = targetingFigureLayout({}, backwards);
  ASSERT_FALSE(bad_volume.ok());
  EXPECT_EQ(bad_volume.error().reason, "bad_feasible_volume");

  FigureOptions tiny;
  tiny.panel_px = 10;
  EXPECT_FALSE(targetingFigureLayout({}, std::nullopt, tiny).ok());
}

}  // namespace
}  // namespace ignav::verification
