// The AAPM TG-43U1 dose-rate formalism for a low-dose-rate seed (Rivard et al., "Update of AAPM
// Task Group No. 43 Report", Med. Phys. 31(3):633-674, 2004): the dose rate per unit air-kerma
// strength at a point given by its distance from the seed's centre and its angle from the seed's
// long axis, from the seed model's published data (configs/seeds/*.yaml, one file per model with
// its citation). Distances of the published tables are in cm, as the report gives them.
#pragma once

#include <string>
#include <vector>

#include "ignav/core/expected.hpp"

namespace ignav::dosimetry {

// One seed model's TG-43U1 data.
struct SeedModel {
  std::string name;                                 // e.g. oncura_6711
  std::string isotope;                              // I-125, Pd-103
  std::string citation;                             // where the numbers are published
  double dose_rate_constant_cGy_per_h_per_U = 0.0;  // Λ, at r0 = 1 cm, θ0 = 90°
  double active_length_cm = 0.0;                    // L of the line-source geometry function
  double half_life_h = 0.0;
  // g_L(r): the radial dose function for the line source.
  std::vector<double> radial_r_cm, radial_g;
  // F(r, θ): the 2D anisotropy function, one row per angle (0-90°; the seed is symmetric about
  // its transverse plane), one column per distance.
  std::vector<double> anisotropy_r_cm, anisotropy_theta_deg;
  std::vector<std::vector<double>> anisotropy_f;
  // φ_an(r): the 1D anisotropy function (the solid-angle average); may be absent.
  std::vector<double> phi_an_r_cm, phi_an;
};

// Reads and checks a seed model file; errors name the file and the field.
Expected<SeedModel> readSeedModel(const std::string& path);
// The same checks on a model made in code.
Status validate(const SeedModel& model);

enum class Formalism {
  kLine2D,   // G_L, g_L and F(r, θ): TG-43U1's 2D formalism
  kPoint1D,  // 1/r², g_P and φ_an(r): the point-source approximation (needs φ_an)
};

// G_L(r, θ) of a line of length `length_cm` (TG-43U1 eq. 4): β / (L r sin θ), and on the axis
// beyond the line 1 / (r² − L²/4); in cm⁻². Infinite on the line itself.
double lineGeometryFactor(double r_cm, double theta_rad, double length_cm);

// g_L(r): linear between the published distances, the first value nearer than the first, and
// log-linear from the last two beyond the last.
double radialDoseFunction(const SeedModel& model, double r_cm);
// g_P(r), the point-source radial dose function derived from g_L (TG-43U1 eq. 11's conversion):
// g_L(r) · G_L(r, θ0) r² / (G_L(r0, θ0) r0²).
double pointRadialDoseFunction(const SeedModel& model, double r_cm);
// F(r, θ): bilinear in r and θ within the table, the nearest published distance outside it.
double anisotropyFunction(const SeedModel& model, double r_cm, double theta_rad);
// φ_an(r): linear in r, the nearest published value outside; NaN when the model has none.
double anisotropyFactor(const SeedModel& model, double r_cm);

// The dose rate per unit air-kerma strength, cGy h⁻¹ U⁻¹, at r from the seed's centre and θ from
// its long axis (θ is ignored by the point-source approximation). NaN for the point source when
// the model has no φ_an.
double doseRatePerUnitStrength(const SeedModel& model, double r_cm, double theta_rad,
                               Formalism formalism = Formalism::kLine2D);

// A permanent implant's total dose from its initial dose rate: the integral of the decaying rate,
// Ḋ0 · T½ / ln 2 (≈ 1.44 · T½).
double permanentImplantDose_cGy(double initial_dose_rate_cGy_per_h, double half_life_h);

}  // namespace ignav::dosimetry
