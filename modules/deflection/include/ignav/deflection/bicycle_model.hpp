// Needle deflection in soft tissue: the extended bicycle model of seed 000 (MODEL.md §10) and its
// plain (λ = 0) case. A bevel-tip needle pushed s mm into tissue moves in the plane (z depth, y
// deflection) with tip angle γ; the tissue lets it slip sideways by α(γ) = λ1 γ² + λ2 γ.
// Pure functions: values in, values out.
#pragma once

#include <string>
#include <vector>

#include "ignav/core/expected.hpp"

namespace ignav::deflection {

// The needle: signed curvature k = tan β / ℓ (1/mm; negative bends towards −y) and wheelbase ℓ.
struct NeedleModel {
  double curvature_per_mm = -1.0 / 400.0;
  double wheelbase_mm = 20.0;
  int slip_sign = -1;  // s in θ̇ = v (k + s·tan α / ℓ); −1 is canonical (MODEL.md A9)
};

// Tissue slip parameters (Table I of seed 000: agar 0.49 / 0.22, plastisol 0.144 / 0.032).
struct Tissue {
  double lambda1 = 0.0;
  double lambda2 = 0.0;
};

// The model's conditions (23) cos α ≠ 0 and (24) 1 − ∂α/∂γ ≠ 0, evaluated exactly over the tip
// angles the needle can take while bending its own way: γ ∈ [−π/2, 0] for k < 0, [0, π/2] else.
struct Admissibility {
  bool admissible = false;
  std::string reason;                               // why not, naming the condition and the angle
  double alpha_min_rad = 0.0, alpha_max_rad = 0.0;  // α over the range
  double slope_min = 0.0, slope_max = 0.0;          // 1 − ∂α/∂γ over the range
};
Admissibility checkAdmissible(const NeedleModel& needle, const Tissue& tissue);

// Where a fit of (λ1, λ2) may start: a per_axis × per_axis grid over λ1 ∈ [−0.5, 2] and
// λ2 ∈ [−0.5, 0.95] (seed 000's tissues lie well inside), less what the model does not admit for
// this needle. Least squares in λ has local minima (a slow drift is fitted, worse, by a small λ2
// as well as by the right large one): a fit tries the best of these besides its own guess.
std::vector<Tissue> tissueGrid(const NeedleModel& needle, int per_axis = 8);

struct PathSample {
  double s_mm = 0.0;  // inserted length (pushed in)
  double z_mm = 0.0;  // depth
  double y_mm = 0.0;  // deflection
  double gamma_rad = 0.0;
};

// The tip path from y = z = γ = 0, sampled every `step_mm` of inserted length from 0 to
// `length_mm` inclusive (the last step may be shorter). Error-controlled Runge–Kutta–Fehlberg
// 7(8), tolerances 1e-12. Errors: non-finite or non-positive values, more than 10⁶ samples, an
// inadmissible tissue, or a path that turns past ±90°.
Expected<std::vector<PathSample>> simulate(const NeedleModel& needle, const Tissue& tissue,
                                           double length_mm, double step_mm);

// The deflection y at each depth z (ascending, ≥ 0), integrating over depth directly.
Expected<std::vector<double>> deflectionAtDepths(const NeedleModel& needle, const Tissue& tissue,
                                                 const std::vector<double>& depths_mm);

struct Observation {
  double depth_mm = 0.0;
  double deflection_mm = 0.0;
};

struct FitOptions {
  Tissue initial{0.2, 0.1};
  bool fit_curvature = false;  // also estimate k (the needle's own curvature)
  // Measurement noise a measured path may carry: depths down to −depth_noise_mm (the entry
  // point picked slightly too deep) and, in the order given, steps back by up to this much. The
  // model reads a depth below 0 as 0 (the needle is straight until it enters).
  double depth_noise_mm = 0.5;
};

struct TissueFit {
  Tissue tissue;
  double curvature_per_mm = 0.0;        // fitted, or the given one
  std::vector<double> standard_errors;  // λ1, λ2 [, k]
  double correlation = 0.0;             // between λ1 and λ2
  double rms_mm = 0.0;
  double max_error_mm = 0.0;              // of the fitted extended model at the observations
  double bicycle_curvature_per_mm = 0.0;  // the plain model fitted to the same data (k only)
  double max_error_bicycle_mm = 0.0;
  int iterations = 0;
};

// Levenberg–Marquardt (Eigen) on the deflection residuals at the observed depths; standard errors
// from the Jacobian at the solution, σ² = RSS / (n − p). The plain bicycle model is fitted to the
// same data for comparison (seed 000's claim: the extended model fits non-circular paths better).
// The observations are one path in the order measured; noise within `depth_noise_mm` is data.
// Refused, naming the observation: non-finite values, a depth further above the entry than the
// tolerance, a step back by more than it (not one path), a path spanning no more depth than the
// noise, too few observations, or a fit that does not converge.
Expected<TissueFit> fitTissue(const NeedleModel& needle, const std::vector<Observation>& observed,
                              const FitOptions& options = {});

}  // namespace ignav::deflection
