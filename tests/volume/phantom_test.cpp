// The phantom as a CT: its noise (what a scanner adds) and its slices (what a scanner averages),
// against closed forms: the normal distribution's moments and the seed's metal, π r² L ΔHU.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "ignav/volume/phantom.hpp"

namespace ignav::volume {
namespace {

// Sample mean, SD and the share within one SD of the mean, of the voxels (all in the gel box).
struct Moments {
  double mean = 0.0, sd = 0.0, within_one_sd = 0.0;
};
Moments moments(const Volume& v) {
  double sum = 0.0, sum2 = 0.0;
  for (const auto x : v.voxels) {
    sum += x;
    sum2 += static_cast<double>(x) * x;
  }
  const auto n = static_cast<double>(v.voxels.size());
  Moments m;
  m.mean = sum / n;
  m.sd = std::sqrt((sum2 - n * m.mean * m.mean) / (n - 1.0));
  std::size_t within = 0;
  for (const auto x : v.voxels)
    within += std::abs(x - m.mean) <= m.sd ? 1 : 0;
  m.within_one_sd = static_cast<double>(within) / n;
  return m;
}

PhantomSpec gelOnly() {
  PhantomSpec spec;
  spec.dims = {48, 48, 32};  // 38 x 38 x 39 mm: all inside the 60 x 60 x 64 mm box
  spec.fiducials_lps_mm.clear();
  return spec;
}

TEST(PhantomNoise, IsGaussianWithTheAskedSdAndRepeatsForItsSeed) {
  PhantomSpec spec = gelOnly();
  spec.noise_sigma_hu = 20.0;
  spec.seed = 7;
  const Volume a = makePhantom(spec).value();
  const Moments m = moments(a);
  // 73,728 voxels: the mean's standard error is 0.07 HU, the SD's 0.05 HU. Rounding to whole HU
  // adds 1/12 HU² (Sheppard): √(400 + 1/12) = 20.002.
  EXPECT_NEAR(m.mean, spec.box_hu, 0.4);
  EXPECT_NEAR(m.sd, std::sqrt(400.0 + 1.0 / 12.0), 0.3);
  // A normal variable lies within one SD of its mean with probability erf(1/√2) = 0.6827; whole
  // HU values exactly on the edge move that by ~1/(√(2π) σ) at most.
  EXPECT_NEAR(m.within_one_sd, 0.6827, 0.02);

  EXPECT_EQ(makePhantom(spec).value().voxels, a.voxels);  // the same seed, the same scan
  spec.seed = 8;
  EXPECT_NE(makePhantom(spec).value().voxels, a.voxels);
  spec.noise_sigma_hu = 0.0;
  const Moments clean = moments(makePhantom(spec).value());
  EXPECT_EQ(clean.mean, spec.box_hu);
  EXPECT_EQ(clean.sd, 0.0);
}

TEST(PhantomNoise, ANegativeOrNonFiniteSdIsRefused) {
  PhantomSpec spec = gelOnly();
  for (double bad : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    spec.noise_sigma_hu = bad;
    const auto v = makePhantom(spec);
    ASSERT_FALSE(v.ok()) << bad;
    EXPECT_NE(v.error().message.find("noise_sigma_hu"), std::string::npos) << v.error().message;
  }
}

TEST(PhantomSlices, ThickerSlicesKeepTheFieldOfViewAndTheSeedsMetal) {
  PhantomSpec spec;  // 64 slices of 1.25 mm: 78.75 mm between the first and the last
  spec.fiducials_lps_mm.clear();
  const auto thick = withSliceSpacing(spec, 2.5);
  ASSERT_TRUE(thick.ok()) << thick.error().message;
  // 78.75 / 2.5 = 31.5 steps, rounded to 32: 33 slices over 80 mm, within half a slice.
  EXPECT_EQ(thick->dims[2], 33);
  EXPECT_EQ(thick->spacing_mm.z(), 2.5);
  EXPECT_EQ(thick->dims[0], spec.dims[0]);
  EXPECT_EQ(thick->dims[1], spec.dims[1]);
  EXPECT_EQ(thick->spacing_mm.x(), spec.spacing_mm.x());
  const Geometry g = phantomGeometry(*thick);
  EXPECT_NEAR(g.toLps(Eigen::Vector3d(0, 0, 0)).z(), -40.0, 1e-12);  // still centred on 0
  EXPECT_NEAR(g.toLps(Eigen::Vector3d(0, 0, 32)).z(), 40.0, 1e-12);
  EXPECT_EQ(withSliceSpacing(spec, 1.25).value().dims[2], 64);  // unchanged when the same

  // A seed across 2.5 mm slices: spread over fewer, thicker voxels, its metal the same,
  // (7000 − 20) HU × π (0.4 mm)² × 3 mm, whatever its tilt.
  for (const Eigen::Vector3d& axis : {Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(0, 0, 1)}) {
    PhantomSpec with = *thick;
    const Volume gel = makePhantom(with).value();
    with.seeds = {{Eigen::Vector3d(0.3, -1.7, 0.9), axis, 3.0, 0.8}};
    const Volume seeded = makePhantom(with).value();
    double metal = 0.0;
    for (std::size_t i = 0; i < seeded.voxels.size(); ++i)
      metal += (seeded.voxels[i] - gel.voxels[i]) * with.spacing_mm.prod();
    const double expected = (with.seed_hu - with.box_hu) * M_PI * 0.4 * 0.4 * 3.0;
    EXPECT_NEAR(metal, expected, 0.003 * expected) << axis.transpose();
  }
}

TEST(PhantomSlices, AnImpossibleSpacingIsRefusedWithItsNumbers) {
  const PhantomSpec spec;
  for (double bad : {0.0, -1.25, std::nan(""), std::numeric_limits<double>::infinity()}) {
    const auto s = withSliceSpacing(spec, bad);
    ASSERT_FALSE(s.ok()) << bad;
    EXPECT_NE(s.error().message.find("positive number of mm"), std::string::npos);
  }
  const auto fine = withSliceSpacing(spec, 0.01);
  ASSERT_FALSE(fine.ok());
  EXPECT_NE(fine.error().message.find("0.01 mm slices across 78.75 mm would take 7876 slices"),
            std::string::npos)
      << fine.error().message;
}

}  // namespace
}  // namespace ignav::volume
