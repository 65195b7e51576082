// The TG-43U1 formalism (tg43.hpp).
#include <algorithm>
#include <cmath>
#include <limits>

#include "ignav/dosimetry/tg43.hpp"

namespace ignav::dosimetry {
namespace {

constexpr double kReferenceDistance_cm = 1.0;       // r0
constexpr double kReferenceAngle_rad = M_PI / 2.0;  // θ0

// Linear interpolation in a table of increasing xs; the end values beyond it.
double linear(const std::vector<double>& xs, const std::vector<double>& ys, double x) {
  if (x <= xs.front()) return ys.front();
  if (x >= xs.back()) return ys.back();
  const auto hi = static_cast<std::size_t>(std::upper_bound(xs.begin(), xs.end(), x) - xs.begin());
  const std::size_t lo = hi - 1;
  const double t = (x - xs[lo]) / (xs[hi] - xs[lo]);
  return ys[lo] + t * (ys[hi] - ys[lo]);
}

// The angle folded onto 0-90°: the seed is symmetric about its transverse plane.
double foldedDegrees(double theta_rad) {
  double deg = std::abs(std::remainder(theta_rad, 2.0 * M_PI)) * 180.0 / M_PI;  // 0-180
  return deg > 90.0 ? 180.0 - deg : deg;
}

}  // namespace

double lineGeometryFactor(double r_cm, double theta_rad, double length_cm) {
  const double z = r_cm * std::cos(theta_rad);            // along the seed
  const double y = std::abs(r_cm * std::sin(theta_rad));  // away from it
  const double half = 0.5 * length_cm;
  if (y < 1e-12 * std::max(1.0, r_cm)) {
    const double d2 = z * z - half * half;
    return d2 > 0.0 ? 1.0 / d2 : std::numeric_limits<double>::infinity();
  }
  // β, the angle the line subtends at the point.
  const double beta = std::atan((z + half) / y) - std::atan((z - half) / y);
  return beta / (length_cm * y);
}

double radialDoseFunction(const SeedModel& model, double r_cm) {
  const auto& r = model.radial_r_cm;
  const auto& g = model.radial_g;
  if (r_cm > r.back()) {
    const std::size_t n = r.size();
    const double slope = std::log(g[n - 1] / g[n - 2]) / (r[n - 1] - r[n - 2]);
    return g[n - 1] * std::exp(slope * (r_cm - r[n - 1]));
  }
  return linear(r, g, r_cm);
}

double pointRadialDoseFunction(const SeedModel& model, double r_cm) {
  const double l = model.active_length_cm;
  return radialDoseFunction(model, r_cm) * lineGeometryFactor(r_cm, kReferenceAngle_rad, l) * r_cm *
         r_cm /
         (lineGeometryFactor(kReferenceDistance_cm, kReferenceAngle_rad, l) *
          kReferenceDistance_cm * kReferenceDistance_cm);
}

double anisotropyFunction(const SeedModel& model, double r_cm, double theta_rad) {
  const auto& rs = model.anisotropy_r_cm;
  const auto& thetas = model.anisotropy_theta_deg;
  const double theta_deg = foldedDegrees(theta_rad);
  // F at the published angle row `k`, interpolated in r.
  const auto atRow = [&](std::size_t k) { return linear(rs, model.anisotropy_f[k], r_cm); };
  if (theta_deg <= thetas.front()) return atRow(0);
  if (theta_deg >= thetas.back()) return atRow(thetas.size() - 1);
  const auto hi = static_cast<std::size_t>(
      std::upper_bound(thetas.begin(), thetas.end(), theta_deg) - thetas.begin());
  const double t = (theta_deg - thetas[hi - 1]) / (thetas[hi] - thetas[hi - 1]);
  return atRow(hi - 1) + t * (atRow(hi) - atRow(hi - 1));
}

double anisotropyFactor(const SeedModel& model, double r_cm) {
  if (model.phi_an.empty()) return std::numeric_limits<double>::quiet_NaN();
  return linear(model.phi_an_r_cm, model.phi_an, r_cm);
}

double doseRatePerUnitStrength(const SeedModel& model, double r_cm, double theta_rad,
                               Formalism formalism) {
  const double lambda = model.dose_rate_constant_cGy_per_h_per_U;
  if (formalism == Formalism::kPoint1D) {
    const double ratio = kReferenceDistance_cm / r_cm;
    return lambda * ratio * ratio * pointRadialDoseFunction(model, r_cm) *
           anisotropyFactor(model, r_cm);
  }
  const double l = model.active_length_cm;
  return lambda * lineGeometryFactor(r_cm, theta_rad, l) /
         lineGeometryFactor(kReferenceDistance_cm, kReferenceAngle_rad, l) *
         radialDoseFunction(model, r_cm) * anisotropyFunction(model, r_cm, theta_rad);
}

double permanentImplantDose_cGy(double initial_dose_rate_cGy_per_h, double half_life_h) {
  return initial_dose_rate_cGy_per_h * half_life_h / std::log(2.0);
}

}  // namespace ignav::dosimetry
