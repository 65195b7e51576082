// Dose-volume histograms and implant metrics (dvh.hpp).
#include "ignav/dosimetry/dvh.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>

#include <fmt/format.h>

namespace ignav::dosimetry {

Expected<DoseVolumeHistogram> DoseVolumeHistogram::of(std::vector<double> doses_Gy,
                                                      double voxel_cm3) {
  if (doses_Gy.empty())
    return makeError(ErrorCode::kInvalidArgument, "a dose-volume histogram needs voxels",
                     "empty_structure");
  if (!std::isfinite(voxel_cm3) || voxel_cm3 <= 0.0)
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("a voxel of {} cm³ is no volume", voxel_cm3), "bad_dose");
  for (std::size_t i = 0; i < doses_Gy.size(); ++i) {
    if (!std::isfinite(doses_Gy[i]) || doses_Gy[i] < 0.0)
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("voxel {}'s dose {} Gy is not a dose", i, doses_Gy[i]),
                       "bad_dose");
  }
  DoseVolumeHistogram h;
  h.voxel_cm3_ = voxel_cm3;
  h.mean_Gy_ =
      std::accumulate(doses_Gy.begin(), doses_Gy.end(), 0.0) / static_cast<double>(doses_Gy.size());
  std::sort(doses_Gy.begin(), doses_Gy.end(), std::greater<>());
  h.sorted_ = std::move(doses_Gy);
  return h;
}

double DoseVolumeHistogram::fractionAtLeast(double dose_Gy) const {
  // sorted_ descending: the voxels at or above are a prefix.
  const auto end = std::upper_bound(sorted_.begin(), sorted_.end(), dose_Gy, std::greater<>());
  return static_cast<double>(end - sorted_.begin()) / static_cast<double>(sorted_.size());
}

double DoseVolumeHistogram::doseToHottestFraction_Gy(double fraction) const {
  const double n = static_cast<double>(sorted_.size());
  // The hottest ceil(fraction · n) voxels; their least dose.
  const auto count = static_cast<std::size_t>(std::clamp(std::ceil(fraction * n - 1e-9), 1.0, n));
  return sorted_[count - 1];
}

double DoseVolumeHistogram::doseToHottestVolume_Gy(double cm3) const {
  return doseToHottestFraction_Gy(cm3 / volume_cm3());
}

std::vector<double> DoseVolumeHistogram::cumulative(double bin_Gy) const {
  std::vector<double> out;
  if (!(bin_Gy > 0.0)) return out;
  for (std::size_t k = 0; static_cast<double>(k) * bin_Gy <= max_Gy(); ++k)
    out.push_back(fractionAtLeast(static_cast<double>(k) * bin_Gy));
  return out;
}

TargetMetrics targetMetrics(const DoseVolumeHistogram& t, double rx_Gy) {
  TargetMetrics m;
  m.d90_percent = 100.0 * t.doseToHottestFraction_Gy(0.9) / rx_Gy;
  m.v100 = t.fractionAtLeast(rx_Gy);
  m.v150 = t.fractionAtLeast(1.5 * rx_Gy);
  m.v200 = t.fractionAtLeast(2.0 * rx_Gy);
  m.homogeneity = m.v100 > 0.0 ? (m.v100 - m.v150) / m.v100 : 0.0;
  return m;
}

OrganMetrics organMetrics(const DoseVolumeHistogram& o, double rx_Gy) {
  OrganMetrics m;
  m.d10_percent = 100.0 * o.doseToHottestFraction_Gy(0.1) / rx_Gy;
  m.d30_percent = 100.0 * o.doseToHottestFraction_Gy(0.3) / rx_Gy;
  m.dmax_percent = 100.0 * o.max_Gy() / rx_Gy;
  m.d2cc_Gy = o.doseToHottestVolume_Gy(2.0);
  m.d01cc_Gy = o.doseToHottestVolume_Gy(0.1);
  m.v100_cm3 = o.volumeAtLeast_cm3(rx_Gy);
  return m;
}

double conformityIndex(const DoseVolumeHistogram& t, double rx_Gy, double isodose_cm3) {
  if (!(isodose_cm3 > 0.0)) return 0.0;
  const double covered_cm3 = t.volumeAtLeast_cm3(rx_Gy);
  return covered_cm3 * covered_cm3 / (t.volume_cm3() * isodose_cm3);
}

}  // namespace ignav::dosimetry
