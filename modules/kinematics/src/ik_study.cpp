#include "ignav/kinematics/ik_study.hpp"

#include <algorithm>
#include <cmath>

namespace ignav::kinematics {

std::size_t IkStudyResult::geometriesWithMeanBelow(double mm) const {
  return static_cast<std::size_t>(std::count_if(geometries.begin(), geometries.end(),
                                                [mm](const auto& g) { return g.mean_mm < mm; }));
}

namespace {

// Visits every grid point (r, z) of the exact feasible area of one instrument.
template <typename Visit>
void forEachFeasibleTarget(const Kinematics& k, double grid_mm, Visit&& visit) {
  const double zc_max = k.instrument().cannula_travel_mm;
  const auto ir_lo = static_cast<long>(std::ceil(k.minRadius_mm() / grid_mm));
  const auto ir_hi = static_cast<long>(std::floor(k.maxRadius_mm() / grid_mm));
  for (long ir = ir_lo; ir <= ir_hi; ++ir) {
    const double r = static_cast<double>(ir) * grid_mm;
    const double z_top = k.tipDepthAtHome_mm(k.styletForRadius_mm(r));
    const auto iz_lo = static_cast<long>(std::ceil((z_top - zc_max) / grid_mm));
    const auto iz_hi = static_cast<long>(std::floor(z_top / grid_mm));
    for (long iz = iz_lo; iz <= iz_hi; ++iz)
      visit(r, static_cast<double>(iz) * grid_mm);
  }
}

}  // namespace

std::vector<IkStudySample> closedFormErrorMap(const Kinematics& k, double grid_mm) {
  std::vector<IkStudySample> out;
  forEachFeasibleTarget(k, grid_mm, [&](double r, double z) {
    out.push_back({r, z, k.inverseClosedForm({0.0, r, z}).error_mm});
  });
  return out;
}

IkStudyResult runIkStudy(const IkStudySet& set, double grid_mm) {
  IkStudyResult result;
  result.set = set;
  double sum = 0.0, sum_sq = 0.0;
  for (double dc : {1.2, 1.6, 2.0, 2.4}) {
    for (double ds : {0.5, 0.7, 0.9, 1.1}) {
      for (double radius : {35.0, 45.0, 50.0, 55.0}) {
        Instrument g;
        g.cannula_inner_diameter_mm = dc;
        g.cannula_outer_diameter_mm = dc + 0.2;
        g.stylet_outer_diameter_mm = ds;
        g.stylet_radius_mm = radius;
        g.stylet_travel_mm = set.stylet_travel_mm;
        g.stylet_curved_length_mm = set.stylet_travel_mm;
        g.cannula_travel_mm = set.cannula_travel_mm;
        g.cannula_deflected_radius_mm = set.deflected_radius_mm;
        g.exit_offset = set.offset;
        const auto k = Kinematics::create(g);
        if (!k) continue;  // every geometry of the sweep is valid; kept total for safety
        IkStudyGeometry geo{dc, ds, radius, 0, 0.0, 0.0};
        double geo_sum = 0.0;
        forEachFeasibleTarget(*k, grid_mm, [&](double r, double z) {
          const Eigen::Vector3d target(0.0, r, z);
          const ClosedFormSolution cf = k->inverseClosedForm(target);
          const auto exact = k->inverse(target);
          if (exact && exact->reachable()) {
            const double e = (k->forward(exact->joints).tip_mm - target).norm();
            result.exact_max_mm = std::max(result.exact_max_mm, e);
          } else {
            result.exact_max_mm = INFINITY;  // a feasible target the solver refused: a bug
          }
          ++geo.targets;
          geo_sum += cf.error_mm;
          geo.max_mm = std::max(geo.max_mm, cf.error_mm);
          sum += cf.error_mm;
          sum_sq += cf.error_mm * cf.error_mm;
          result.clipped += cf.clipped ? 1 : 0;
        });
        geo.mean_mm = geo.targets ? geo_sum / static_cast<double>(geo.targets) : 0.0;
        result.targets += geo.targets;
        result.max_mm = std::max(result.max_mm, geo.max_mm);
        result.geometries.push_back(geo);
      }
    }
  }
  if (result.targets > 0) {
    const auto n = static_cast<double>(result.targets);
    result.mean_mm = sum / n;
    result.variance_mm2 = std::max(0.0, sum_sq / n - result.mean_mm * result.mean_mm);
  }
  return result;
}

}  // namespace ignav::kinematics
