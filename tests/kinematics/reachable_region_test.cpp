// ReachableRegion (the feasible volume drawn on slices) must answer as Kinematics::inverse does,
// everywhere: at random, and at and around every limit where a table could be wrong.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "ignav/kinematics/reachable_region.hpp"
#include "test_instruments.hpp"

namespace ignav::kinematics {
namespace {

constexpr double kPi = 3.14159265358979323846;

bool byInverse(const Kinematics& k, const Eigen::Vector3d& p) {
  const auto s = k.inverse(p);
  return s.ok() && s->reachable();
}

std::vector<Instrument> instruments() {
  Instrument rigid = testing::paperInstrument();  // r_min = 0: the table starts on the axis
  rigid.stylet_outer_diameter_mm = rigid.cannula_inner_diameter_mm;
  rigid.cannula_deflected_radius_mm = std::numeric_limits<double>::infinity();
  rigid.exit_offset = ExitOffset::kNone;
  return {testing::paperInstrument(), rigid};
}

TEST(ReachableRegion, AgreesWithInverseAtRandom) {
  for (const Instrument& g : instruments()) {
    const auto k = Kinematics::create(g).value();
    const ReachableRegion region(k);
    const auto box = region.boundingBox();
    std::mt19937_64 rng(11);
    // Uniform over the box grown by 5 mm on every side: inside, outside and beyond it.
    std::uniform_real_distribution<double> x(box[0].x() - 5, box[7].x() + 5),
        y(box[0].y() - 5, box[7].y() + 5), z(box[0].z() - 5, box[7].z() + 5);
    int reachable = 0;
    for (int i = 0; i < 400000; ++i) {
      const Eigen::Vector3d p(x(rng), y(rng), z(rng));
      const bool expected = byInverse(k, p);
      reachable += expected;
      ASSERT_EQ(region.contains(p), expected) << p.transpose();
    }
    EXPECT_GT(reachable, 10000);  // the box is not mostly empty
  }
}

TEST(ReachableRegion, AgreesWithInverseAtEveryLimit) {
  for (const Instrument& g : instruments()) {
    const auto k = Kinematics::create(g).value();
    const ReachableRegion region(k);
    const double zc_max = g.cannula_travel_mm;
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> angle(-kPi, kPi), unit(0.0, 1.0);
    const double band = 1e-4;  // about where most intervals' bands are
    const std::vector<double> offsets = {0.0,   1e-12,    -1e-12,    1e-9, -1e-9, 1e-6, -1e-6, band,
                                         -band, 2 * band, -2 * band, 1e-3, -1e-3, 0.05, -0.05};
    int checked = 0;
    for (int i = 0; i < 4000; ++i) {
      const double a = angle(rng);
      const double r = k.minRadius_mm() + unit(rng) * (k.maxRadius_mm() - k.minRadius_mm());
      const double top = k.tipDepthAtHome_mm(k.styletForRadius_mm(r));
      for (double d : offsets) {
        // Around the shallowest and deepest tip depths at this radius...
        for (double z : {top + d, top - zc_max + d}) {
          const Eigen::Vector3d p(r * std::cos(a), r * std::sin(a), z);
          ASSERT_EQ(region.contains(p), byInverse(k, p)) << p.transpose() << " d " << d;
          ++checked;
        }
        // ...and around the smallest and largest radius, at a depth between.
        for (double rr : {k.minRadius_mm() + d, k.maxRadius_mm() + d}) {
          if (rr < 0.0) continue;
          const double zz = k.tipDepthAtHome_mm(k.styletForRadius_mm(rr)) - unit(rng) * zc_max;
          const Eigen::Vector3d p(rr * std::cos(a), rr * std::sin(a), zz);
          ASSERT_EQ(region.contains(p), byInverse(k, p)) << p.transpose() << " d " << d;
          ++checked;
        }
      }
    }
    EXPECT_GT(checked, 200000);
    // The table decides nearly every radius itself (the rest is near r_min, where depth is steep).
    EXPECT_GT(region.tableShare(), 0.99) << "widest band " << region.widestBand_mm() << " mm";
  }
}

TEST(ReachableRegion, BoxHoldsEveryPoseAndNonFiniteIsOutside) {
  const auto k = Kinematics::create(testing::paperInstrument()).value();
  const ReachableRegion region(k);
  const auto box = region.boundingBox();
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Instrument& g = k.instrument();
  for (int i = 0; i < 20000; ++i) {
    Joints j;
    j.theta_c_rad = (2 * unit(rng) - 1) * kPi;
    j.z_c_mm = unit(rng) * g.cannula_travel_mm;
    j.z_s_mm = unit(rng) * g.stylet_travel_mm;
    const Eigen::Vector3d tip = k.forward(j).tip_mm;
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(tip[a], box[0][a]);
      EXPECT_LE(tip[a], box[7][a]);
    }
    EXPECT_TRUE(region.contains(tip)) << tip.transpose();
  }
  EXPECT_FALSE(region.contains(Eigen::Vector3d(std::nan(""), 0, 0)));
}

}  // namespace
}  // namespace ignav::kinematics
