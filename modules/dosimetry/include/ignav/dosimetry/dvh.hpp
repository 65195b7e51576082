// Dose-volume histograms and the metrics an implant is judged by (issue 42, part 2): from the dose
// at each voxel of a structure, exactly (sorted doses, no bins), and the cumulative curve on bins
// for plots and exchange.
#pragma once

#include <vector>

#include "ignav/core/expected.hpp"

namespace ignav::dosimetry {

class DoseVolumeHistogram {
 public:
  // The dose (Gy) at each voxel of the structure, each voxel `voxel_cm3` of volume. Refused when
  // empty, a dose is not finite or negative, or the volume is not positive.
  static Expected<DoseVolumeHistogram> of(std::vector<double> voxel_doses_Gy, double voxel_cm3);

  double volume_cm3() const { return voxel_cm3_ * static_cast<double>(sorted_.size()); }
  double min_Gy() const { return sorted_.back(); }
  double max_Gy() const { return sorted_.front(); }
  double mean_Gy() const { return mean_Gy_; }
  // V(D): the fraction of the structure (0-1), or its volume, that receives at least `dose_Gy`.
  double fractionAtLeast(double dose_Gy) const;
  double volumeAtLeast_cm3(double dose_Gy) const { return volume_cm3() * fractionAtLeast(dose_Gy); }
  // D_x: the least dose the hottest `fraction` (0-1] of the structure receives (D90: 0.9).
  double doseToHottestFraction_Gy(double fraction) const;
  // D_v: the least dose the hottest `cm3` of it receive (D2cc: 2); its maximum for less than a
  // voxel, its minimum for more than it holds.
  double doseToHottestVolume_Gy(double cm3) const;
  // The cumulative curve: the fraction receiving at least k · bin_Gy, for k = 0 … up to its max.
  std::vector<double> cumulative(double bin_Gy) const;

 private:
  std::vector<double> sorted_;  // descending
  double voxel_cm3_ = 0.0, mean_Gy_ = 0.0;
};

// What a permanent prostate implant is judged by, against the prescription (Gy).
struct TargetMetrics {
  double d90_percent = 0.0;                   // D90 as a percentage of the prescription
  double v100 = 0.0, v150 = 0.0, v200 = 0.0;  // fractions receiving ≥ 100/150/200 %
  double homogeneity = 0.0;                   // (V100 − V150) / V100 (1: no hot spots)
};
TargetMetrics targetMetrics(const DoseVolumeHistogram& target, double prescription_Gy);

struct OrganMetrics {
  double d10_percent = 0.0, d30_percent = 0.0, dmax_percent = 0.0;  // of the prescription
  double d2cc_Gy = 0.0, d01cc_Gy = 0.0;                             // the hottest 2 cc, 0.1 cc
  double v100_cm3 = 0.0;  // volume receiving ≥ the prescription
};
OrganMetrics organMetrics(const DoseVolumeHistogram& organ, double prescription_Gy);

// Paddick's conformity index: (target volume within the prescription isodose)² / (target volume
// · prescription isodose volume), 1 for a perfect fit; `isodose_cm3` the whole grid's volume at or
// above the prescription.
double conformityIndex(const DoseVolumeHistogram& target, double prescription_Gy,
                       double isodose_cm3);

}  // namespace ignav::dosimetry
