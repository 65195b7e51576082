// The needle's tip and centreline on phantoms whose needle is known exactly: a cannula and a
// stylet drawn as solid metal with the scanner's blur and the voxels' partial volume, straight and
// curved like the paper's stylet (R 35.5 mm), clean and with CT noise.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "ignav/verification/needle_detection.hpp"
#include "ignav/verification/seed_detection.hpp"
#include "ignav/volume/phantom.hpp"
#include "polyline.hpp"

namespace ignav::verification {
namespace {

using ::ignav::test::distanceToPolyline;

using volume::PhantomSpec;

struct Needle {
  std::vector<Eigen::Vector3d> cannula, stylet;  // LPS, the stylet's last point is the tip
};

// A cannula coming in along `insertion` from outside the scan to `cannula_tip`, then a stylet
// leaving it: straight for radius 0, else an arc of that radius bending towards `bend` over
// `stylet_mm` of arc.
Needle makeNeedle(const Eigen::Vector3d& cannula_tip, const Eigen::Vector3d& insertion,
                  const Eigen::Vector3d& bend, double stylet_mm, double radius_mm) {
  const Eigen::Vector3d d = insertion.normalized();
  const Eigen::Vector3d n = (bend - bend.dot(d) * d).normalized();
  Needle out;
  for (double s = -80.0; s <= 0.0; s += 0.5)
    out.cannula.push_back(cannula_tip + s * d);
  for (double s = 0.0; s <= stylet_mm + 1e-9; s += 0.25) {
    if (radius_mm <= 0.0) {
      out.stylet.push_back(cannula_tip + s * d);
    } else {
      const double a = s / radius_mm;
      out.stylet.push_back(cannula_tip + radius_mm * std::sin(a) * d +
                           radius_mm * (1.0 - std::cos(a)) * n);
    }
  }
  return out;
}

volume::Volume render(const Needle& needle, double noise_hu, double slice_mm) {
  PhantomSpec spec;
  if (slice_mm > 0.0) spec = volume::withSliceSpacing(spec, slice_mm).value();
  spec.noise_sigma_hu = noise_hu;
  spec.seed = 5;
  volume::appendWire(spec, needle.cannula, 2.1);  // stainless steel cannula (1.9/2.1 mm)
  volume::appendWire(spec, needle.stylet, 1.2);   // nitinol stylet (1.2 mm)
  auto v = volume::makePhantom(spec);
  EXPECT_TRUE(v.ok()) << v.error().message;
  return std::move(v).value();
}

struct Case {
  const char* name;
  Eigen::Vector3d cannula_tip, insertion, bend;
  double stylet_mm, radius_mm;
};

const Case kCases[] = {
    {"straight, oblique", {3.0, -2.0, 4.0}, {0.3, -0.2, -1.0}, {1, 0, 0}, 14.0, 0.0},
    {"curved R 35.5, 30 mm out", {-6.0, 2.0, 12.0}, {0.05, 0.1, -1.0}, {1, 0.3, 0}, 30.0, 35.5},
    {"curved R 35.5, 12 mm out", {4.0, 5.0, 0.0}, {-0.2, 0.0, -1.0}, {0, 1, 0}, 12.0, 35.5},
};

// Worst tip error over the cases (and the centreline's worst distance from the true needle).
std::pair<double, double> worstErrors(double noise_hu, double slice_mm) {
  double tip_worst = 0.0, line_worst = 0.0;
  for (const auto& c : kCases) {
    const Needle needle = makeNeedle(c.cannula_tip, c.insertion, c.bend, c.stylet_mm, c.radius_mm);
    NeedleSearch search;
    search.insertion_lps = c.insertion;
    const auto found = findNeedles(render(needle, noise_hu, slice_mm), search);
    EXPECT_TRUE(found.ok()) << found.error().message;
    if (!found.ok()) continue;
    EXPECT_EQ(found->needles.size(), 1u) << c.name << ": " << found->summary;
    if (found->needles.empty()) continue;
    const auto& n = found->needles.front();
    const double tip_error = (n.tip_lps_mm - needle.stylet.back()).norm();
    std::vector<Eigen::Vector3d> truth = needle.cannula;
    truth.insert(truth.end(), needle.stylet.begin(), needle.stylet.end());
    double line_error = 0.0;
    for (const auto& p : n.centreline_lps_mm)
      line_error = std::max(line_error, distanceToPolyline(truth, p));
    const Eigen::Vector3d true_direction =
        (needle.stylet.back() - needle.stylet[needle.stylet.size() - 2]).normalized();
    EXPECT_GT(n.direction_lps.dot(true_direction), std::cos(5.0 * M_PI / 180.0)) << c.name;
    std::cout << c.name << ", " << noise_hu << " HU, slices " << slice_mm << ": tip off by "
              << tip_error << " mm, centreline within " << line_error << " mm, "
              << n.centreline_lps_mm.size() << " points over " << n.visible_length_mm << " mm\n";
    tip_worst = std::max(tip_worst, tip_error);
    line_worst = std::max(line_worst, line_error);
  }
  return {tip_worst, line_worst};
}

TEST(NeedleDetection, TipWithinATenthOfAMillimetreOnTheCleanPhantom) {
  const auto [tip, line] = worstErrors(0.0, 0.0);
  EXPECT_LT(tip, 0.1);
  EXPECT_LT(line, 0.3);
}

TEST(NeedleDetection, TipWithinThreeTenthsWithNoiseAndThickSlices) {
  for (double slice : {1.25, 2.5}) {
    const auto [tip, line] = worstErrors(25.0, slice);
    EXPECT_LT(tip, 0.3) << slice;
    EXPECT_LT(line, 0.5) << slice;
  }
}

TEST(NeedleDetection, SeedsMarkersAndBoneAreNotNeedles) {
  PhantomSpec spec;
  spec.seeds.push_back({{5.0, 5.0, 5.0}, {0.3, 0.2, 1.0}, 3.0, 0.8});
  // A thick bright rod (bone-like, 8 mm across): long, but no wire.
  std::vector<Eigen::Vector3d> rod{{-15, -15, -20}, {-15, -15, 10}};
  volume::appendWire(spec, rod, 8.0);
  // A thin wire lying across the insertion (a guide wire, a calcified vessel's wall).
  std::vector<Eigen::Vector3d> across{{-25, 12, -12}, {20, 14, -10}};
  volume::appendWire(spec, across, 1.0);
  auto v = volume::makePhantom(spec);
  ASSERT_TRUE(v.ok());
  NeedleSearch search;
  search.insertion_lps = {0, 0, -1};
  search.markers_lps_mm = spec.fiducials_lps_mm;
  const auto found = findNeedles(*v, search);
  ASSERT_TRUE(found.ok());
  EXPECT_TRUE(found->needles.empty()) << found->summary;
  EXPECT_NE(found->summary.find("1 long group too wide"), std::string::npos) << found->summary;
  EXPECT_NE(found->summary.find("1 not along the insertion"), std::string::npos) << found->summary;
  // The seed search still finds the seed beside the rod.
  SeedSearch seeds;
  seeds.markers_lps_mm = spec.fiducials_lps_mm;
  const auto s = findSeeds(*v, seeds);
  ASSERT_TRUE(s.ok());
  EXPECT_EQ(s->seeds.size(), 1u) << s->summary;
}

TEST(NeedleDetection, BadSearchesAreRefusedNamingTheSetting) {
  const auto v = volume::makePhantom(PhantomSpec{}).value();
  NeedleSearch zero;
  zero.insertion_lps = Eigen::Vector3d::Zero();
  auto r = findNeedles(v, zero);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("insertion_lps"), std::string::npos);
  NeedleSearch step;
  step.step_mm = std::nan("");
  r = findNeedles(v, step);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("step_mm"), std::string::npos);
  NeedleSearch nothing;  // the plain phantom: fiducials only
  nothing.markers_lps_mm = PhantomSpec{}.fiducials_lps_mm;
  r = findNeedles(v, nothing);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->needles.empty());
}

}  // namespace
}  // namespace ignav::verification
