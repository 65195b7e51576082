// What an organ at risk may receive from a seed plan (issue 42), in percent of the prescription:
// kept apart from the plan so a site file (anatomy) can carry them.
#pragma once

#include <cmath>
#include <limits>

namespace ignav::dosimetry {

// NaN: not limited.
struct OrganLimits {
  double d10_percent = std::numeric_limits<double>::quiet_NaN();   // e.g. urethra 150
  double d2cc_percent = std::numeric_limits<double>::quiet_NaN();  // e.g. rectum 100
  double dmax_percent = std::numeric_limits<double>::quiet_NaN();
  bool any() const {
    return std::isfinite(d10_percent) || std::isfinite(d2cc_percent) || std::isfinite(dmax_percent);
  }
};

}  // namespace ignav::dosimetry
