// Dose-volume histograms and implant metrics (issue 42, part 2) against closed forms: a point
// source's inverse-square dose in a sphere around it, voxelised finely, whose DVH is
// V(≥D)/V = (r_D/R)³ with r_D = √(k/D).
#include <gtest/gtest.h>

#include <cmath>

#include "ignav/dosimetry/dvh.hpp"

namespace ignav::dosimetry {
namespace {

constexpr double kR_mm = 10.0;  // the sphere
constexpr double kK = 100.0;    // D(r) = k / r² Gy, r in mm: 1 Gy at its surface
constexpr double kVoxel_mm = 0.2;

// The dose at every voxel centre of the sphere (the centres off the source by half a voxel).
DoseVolumeHistogram sphere() {
  std::vector<double> doses;
  const int n = static_cast<int>(kR_mm / kVoxel_mm);
  for (int i = -n; i < n; ++i)
    for (int j = -n; j < n; ++j)
      for (int k = -n; k < n; ++k) {
        const double x = (i + 0.5) * kVoxel_mm, y = (j + 0.5) * kVoxel_mm,
                     z = (k + 0.5) * kVoxel_mm;
        const double r2 = x * x + y * y + z * z;
        if (r2 <= kR_mm * kR_mm) doses.push_back(kK / r2);
      }
  return DoseVolumeHistogram::of(std::move(doses), std::pow(kVoxel_mm / 10.0, 3)).value();
}

double radiusAt_mm(double dose_Gy) {
  return std::sqrt(kK / dose_Gy);
}
// The closed form: the fraction of the sphere at or above `dose_Gy`, (r_D / R)³.
double closedFormFraction(double dose_Gy) {
  return std::pow(radiusAt_mm(dose_Gy) / kR_mm, 3);
}

TEST(Dvh, APointSourceInASphereHasTheClosedFormHistogram) {
  const auto h = sphere();
  const double volume_cm3 = 4.0 / 3.0 * M_PI * std::pow(kR_mm / 10.0, 3);
  EXPECT_NEAR(h.volume_cm3() / volume_cm3, 1.0, 0.002);
  EXPECT_NEAR(h.min_Gy(), 1.0, 0.01);
  // V(≥ D) = (r_D / R)³.
  for (const double dose : {1.5, 2.0, 4.0, 10.0})
    EXPECT_NEAR(h.fractionAtLeast(dose), closedFormFraction(dose), 0.002) << dose;
  // D_x: (r / R)³ = x, D = k / r².
  for (const double x : {0.9, 0.5, 0.1}) {
    const double expected = kK / std::pow(kR_mm * std::cbrt(x), 2);
    EXPECT_NEAR(h.doseToHottestFraction_Gy(x) / expected, 1.0, 0.003) << x;
  }
  // D2cc: the hottest 2 cm³ lie within r = R·(2 / V)^(1/3).
  const double r2cc_mm = kR_mm * std::cbrt(2.0 / volume_cm3);
  EXPECT_NEAR(h.doseToHottestVolume_Gy(2.0) / (kK / (r2cc_mm * r2cc_mm)), 1.0, 0.003);
  // The mean: ∫ k/r² 4πr² dr / (4/3 π R³) = 3k / R².
  EXPECT_NEAR(h.mean_Gy() / (3.0 * kK / (kR_mm * kR_mm)), 1.0, 0.01);
  // The cumulative curve, 0.5 Gy bins: all of it at 0 and 0.5 Gy, then the closed form.
  const auto curve = h.cumulative(0.5);
  EXPECT_DOUBLE_EQ(curve[0], 1.0);
  EXPECT_DOUBLE_EQ(curve[1], 1.0);
  EXPECT_NEAR(curve[4], closedFormFraction(2.0), 0.002);
}

TEST(Dvh, TheImplantMetricsReadTheHistogramAgainstThePrescription) {
  const auto h = sphere();
  const double rx_Gy = 2.0;  // the prescription isodose at r = √50 = 7.07 mm
  const auto t = targetMetrics(h, rx_Gy);
  const double v = closedFormFraction(rx_Gy);
  EXPECT_NEAR(t.v100, v, 0.002);
  EXPECT_NEAR(t.v150, closedFormFraction(3.0), 0.002);
  EXPECT_NEAR(t.v200, closedFormFraction(4.0), 0.002);
  EXPECT_NEAR(t.d90_percent, 100.0 * kK / std::pow(kR_mm * std::cbrt(0.9), 2) / rx_Gy, 0.3);
  EXPECT_NEAR(t.homogeneity, (t.v100 - t.v150) / t.v100, 1e-12);
  const auto o = organMetrics(h, rx_Gy);
  EXPECT_NEAR(o.d10_percent, 100.0 * kK / std::pow(kR_mm * std::cbrt(0.1), 2) / rx_Gy, 0.5);
  EXPECT_NEAR(o.v100_cm3, v * h.volume_cm3(), 0.01);
  EXPECT_DOUBLE_EQ(o.dmax_percent, 100.0 * h.max_Gy() / rx_Gy);
  // Paddick: the isodose a sphere of r_rx inside the target, so CI = (r_rx / R)³.
  const double isodose_cm3 = 4.0 / 3.0 * M_PI * std::pow(radiusAt_mm(rx_Gy) / 10.0, 3);
  EXPECT_NEAR(conformityIndex(h, rx_Gy, isodose_cm3), v, 0.003);
}

TEST(Dvh, BadDosesAreRefused) {
  EXPECT_EQ(DoseVolumeHistogram::of({}, 0.001).error().reason, "empty_structure");
  EXPECT_EQ(DoseVolumeHistogram::of({1.0, std::nan("")}, 0.001).error().reason, "bad_dose");
  EXPECT_NE(DoseVolumeHistogram::of({1.0, -2.0}, 0.001).error().message.find("voxel 1"),
            std::string::npos);
  EXPECT_EQ(DoseVolumeHistogram::of({1.0}, 0.0).error().reason, "bad_dose");
  // One voxel: every D_x is its dose.
  const auto one = DoseVolumeHistogram::of({3.0}, 0.001).value();
  EXPECT_DOUBLE_EQ(one.doseToHottestFraction_Gy(0.9), 3.0);
  EXPECT_DOUBLE_EQ(one.doseToHottestVolume_Gy(2.0), 3.0);
  EXPECT_DOUBLE_EQ(one.fractionAtLeast(3.0), 1.0);  // at least: equal counts
}

}  // namespace
}  // namespace ignav::dosimetry
