// The paper's IK simulation (Torabi 2014 §IV, MODEL.md §7): how far the closed-form inverse
// lands from targets over many instrument geometries, against the exact solver.
#pragma once

#include <string>
#include <vector>

#include "ignav/kinematics/solver.hpp"

namespace ignav::kinematics {

struct IkStudySet {
  std::string label;
  ExitOffset offset = ExitOffset::kNone;  // model the FK uses to score the closed form
  double deflected_radius_mm = 550.0;     // Rd
  double stylet_travel_mm = 40.0;         // zs_max (= L0)
  double cannula_travel_mm = 40.0;        // zc_max
};

// One geometry of the sweep and its closed-form error statistics.
struct IkStudyGeometry {
  double cannula_inner_diameter_mm, stylet_outer_diameter_mm, stylet_radius_mm;
  std::size_t targets = 0;
  double mean_mm = 0.0, max_mm = 0.0;
};

struct IkStudyResult {
  IkStudySet set;
  std::size_t targets = 0;
  std::size_t clipped = 0;  // closed-form joints outside their ranges (clipped before FK)
  double mean_mm = 0.0, max_mm = 0.0, variance_mm2 = 0.0;
  double exact_max_mm = 0.0;  // the exact solver's worst FK(IK(p)) - p over the same targets
  std::vector<IkStudyGeometry> geometries;
  std::size_t geometriesWithMeanBelow(double mm) const;
};

// A target of the study: the plane θc = 0 (x = 0), so (r, z) = (y, z).
struct IkStudySample {
  double r_mm, z_mm, error_mm;
};

// The paper's 64 geometries: dc ∈ {1.2, 1.6, 2.0, 2.4}, ds ∈ {0.5, 0.7, 0.9, 1.1},
// R ∈ {35, 45, 50, 55}; targets on a grid_mm grid over the exact feasible (r, z) area.
IkStudyResult runIkStudy(const IkStudySet& set, double grid_mm = 0.5);

// The closed-form error over the feasible (r, z) grid of one instrument (for a heat map).
std::vector<IkStudySample> closedFormErrorMap(const Kinematics& kinematics, double grid_mm);

}  // namespace ignav::kinematics
