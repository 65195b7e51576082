#include "ignav/deflection/bicycle_model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include <Eigen/Dense>
#include <boost/numeric/odeint.hpp>
#include <unsupported/Eigen/LevenbergMarquardt>
#include <unsupported/Eigen/NumericalDiff>

namespace ignav::deflection {
namespace {

namespace odeint = boost::numeric::odeint;
using State = std::array<double, 3>;

constexpr double kTolerance = 1e-12;
constexpr std::size_t kMaxSamples = 1'000'000;

double alpha(const Tissue& t, double gamma) {
  return t.lambda1 * gamma * gamma + t.lambda2 * gamma;
}
double slope(const Tissue& t, double gamma) {  // 1 − ∂α/∂γ
  return 1.0 - (2.0 * t.lambda1 * gamma + t.lambda2);
}

// dγ/ds: the heading rate per inserted length, through γ = θ + α (eq 17).
double turnRate(const NeedleModel& n, const Tissue& t, double gamma) {
  const double f = std::tan(alpha(t, gamma));
  return (n.curvature_per_mm + n.slip_sign * f / n.wheelbase_mm) / slope(t, gamma);
}

Status checkInputs(const NeedleModel& n, const Tissue& t) {
  if (!std::isfinite(n.curvature_per_mm) || !std::isfinite(n.wheelbase_mm) ||
      !std::isfinite(t.lambda1) || !std::isfinite(t.lambda2)) {
    return makeError(ErrorCode::kInvalidArgument, "k, ℓ, λ1 and λ2 must be finite");
  }
  if (!(n.wheelbase_mm > 0)) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("wheelbase ℓ = {} mm must be positive", n.wheelbase_mm));
  }
  if (n.slip_sign != 1 && n.slip_sign != -1) {
    return makeError(ErrorCode::kInvalidArgument, "slip_sign must be +1 or -1");
  }
  const auto a = checkAdmissible(n, t);
  if (!a.admissible) return makeError(ErrorCode::kDegenerate, a.reason, "inadmissible");
  return Ok{};
}

}  // namespace

Admissibility checkAdmissible(const NeedleModel& needle, const Tissue& tissue) {
  Admissibility out;
  const double lo = needle.curvature_per_mm > 0 ? 0.0 : -M_PI / 2;
  const double hi = needle.curvature_per_mm < 0 ? 0.0 : M_PI / 2;
  // α is quadratic: its extremes are at the ends and at the vertex, if inside.
  std::vector<double> at = {lo, hi};
  if (tissue.lambda1 != 0.0) {
    const double vertex = -tissue.lambda2 / (2.0 * tissue.lambda1);
    if (vertex > lo && vertex < hi) at.push_back(vertex);
  }
  out.alpha_min_rad = out.alpha_max_rad = alpha(tissue, at[0]);
  double worst_gamma = at[0];
  for (double g : at) {
    const double a = alpha(tissue, g);
    out.alpha_min_rad = std::min(out.alpha_min_rad, a);
    out.alpha_max_rad = std::max(out.alpha_max_rad, a);
    if (std::abs(a) > std::abs(alpha(tissue, worst_gamma))) worst_gamma = g;
  }
  // 1 − α' is linear in γ: its ends bound it.
  out.slope_min = std::min(slope(tissue, lo), slope(tissue, hi));
  out.slope_max = std::max(slope(tissue, lo), slope(tissue, hi));
  // α(0) = 0, so cos α ≠ 0 on the range exactly when |α| < π/2 throughout (23).
  if (std::abs(alpha(tissue, worst_gamma)) >= M_PI / 2) {
    out.reason = fmt::format(
        "(23) fails: α(γ) = λ1γ² + λ2γ reaches {:.4f} rad at γ = {:.4f} rad, so cos α = 0 on "
        "[{:.4f}, {:.4f}]",
        alpha(tissue, worst_gamma), worst_gamma, lo, hi);
    return out;
  }
  if (out.slope_min <= 0.0 && out.slope_max >= 0.0) {
    const double zero = (1.0 - tissue.lambda2) / (2.0 * tissue.lambda1);
    out.reason = fmt::format(
        "(24) fails: 1 − ∂α/∂γ = 1 − 2λ1γ − λ2 is zero at γ = {:.4f} rad within [{:.4f}, {:.4f}]",
        tissue.lambda1 != 0.0 ? zero : 0.0, lo, hi);
    return out;
  }
  out.admissible = true;
  return out;
}

std::vector<Tissue> tissueGrid(const NeedleModel& needle, int per_axis) {
  std::vector<Tissue> out;
  const int n = std::max(per_axis, 2);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const Tissue t{-0.5 + 2.5 * i / (n - 1), -0.5 + 1.45 * j / (n - 1)};
      if (checkAdmissible(needle, t).admissible) out.push_back(t);
    }
  }
  return out;
}

Expected<std::vector<PathSample>> simulate(const NeedleModel& needle, const Tissue& tissue,
                                           double length_mm, double step_mm) {
  if (auto ok = checkInputs(needle, tissue); !ok) return ok.error();
  if (!std::isfinite(length_mm) || !(length_mm > 0) || !std::isfinite(step_mm) || !(step_mm > 0)) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("length {} mm and step {} mm must be positive and finite", length_mm, step_mm));
  }
  const double count = std::ceil(length_mm / step_mm - 1e-12) + 1;
  if (count > static_cast<double>(kMaxSamples)) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{:.0f} samples asked; at most {}", count, kMaxSamples));
  }
  std::vector<double> times;
  for (std::size_t i = 0; i + 1 < static_cast<std::size_t>(count); ++i)
    times.push_back(static_cast<double>(i) * step_mm);
  times.push_back(length_mm);

  // Past ±90° the model no longer holds and tan α heads for its pole, where the step control
  // would crawl for ever: stop moving there and refuse the path below.
  double turned_at = std::numeric_limits<double>::quiet_NaN();
  auto rhs = [&](const State& x, State& dx, double s) {
    const double gamma = x[2];
    if (std::abs(gamma) >= M_PI / 2) {
      if (!(turned_at <= s)) turned_at = s;
      dx = {0.0, 0.0, 0.0};
      return;
    }
    const double c = std::cos(alpha(tissue, gamma));
    dx[0] = std::cos(gamma) / c;  // z
    dx[1] = std::sin(gamma) / c;  // y
    dx[2] = turnRate(needle, tissue, gamma);
  };
  std::vector<PathSample> out;
  State x{0.0, 0.0, 0.0};
  odeint::integrate_times(
      odeint::make_controlled(kTolerance, kTolerance, odeint::runge_kutta_fehlberg78<State>()), rhs,
      x, times.begin(), times.end(), step_mm / 4, [&](const State& st, double s) {
        out.push_back({s, st[0], st[1], st[2]});
      });
  for (const auto& p : out) {
    if (std::abs(p.gamma_rad) >= M_PI / 2 && !(turned_at <= p.s_mm)) turned_at = p.s_mm;
  }
  if (std::isfinite(turned_at)) {
    return makeError(ErrorCode::kDegenerate,
                     fmt::format("the path turns past 90° at s = {:.2f} mm; the model holds "
                                 "only for |γ| < 90°",
                                 turned_at),
                     "turned_back");
  }
  return out;
}

Expected<std::vector<double>> deflectionAtDepths(const NeedleModel& needle, const Tissue& tissue,
                                                 const std::vector<double>& depths_mm) {
  if (auto ok = checkInputs(needle, tissue); !ok) return ok.error();
  for (std::size_t i = 0; i < depths_mm.size(); ++i) {
    if (!std::isfinite(depths_mm[i]) || depths_mm[i] < 0 ||
        (i > 0 && depths_mm[i] < depths_mm[i - 1])) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("depth[{}] = {} mm: depths must be finite, ≥ 0 and ascending", i,
                                   depths_mm[i]));
    }
  }
  if (depths_mm.empty()) return std::vector<double>{};
  // Over depth z: dy/dz = tan γ, dγ/dz = (dγ/ds) / (dz/ds).
  using State2 = std::array<double, 2>;
  bool turned = false;
  auto rhs = [&](const State2& x, State2& dx, double /*z*/) {
    const double gamma = x[1];
    const double cg = std::cos(gamma);
    if (cg <= 1e-9) {
      turned = true;
      dx = {0.0, 0.0};
      return;
    }
    dx[0] = std::tan(gamma);
    dx[1] = turnRate(needle, tissue, gamma) * std::cos(alpha(tissue, gamma)) / cg;
  };
  std::vector<double> times;
  if (depths_mm.front() > 0) times.push_back(0.0);
  times.insert(times.end(), depths_mm.begin(), depths_mm.end());
  std::vector<double> ys;
  State2 x{0.0, 0.0};
  const double first_step = std::max(1e-3, (depths_mm.back() + 1.0) / 1000.0);
  if (times.size() == 1) return std::vector<double>{0.0};
  odeint::integrate_times(
      odeint::make_controlled(kTolerance, kTolerance, odeint::runge_kutta_fehlberg78<State2>()),
      rhs, x, times.begin(), times.end(), first_step,
      [&](const State2& st, double) { ys.push_back(st[0]); });
  if (turned) {
    return makeError(ErrorCode::kDegenerate, "the path turns past 90° before the deepest sample",
                     "turned_back");
  }
  if (depths_mm.front() > 0) ys.erase(ys.begin());
  return ys;
}

namespace {

// Residuals y_model(z_i) − y_i for the parameters x: (λ1, λ2[, k]) or, for the plain bicycle
// model, (k).
struct Residuals : Eigen::DenseFunctor<double> {
  enum class Kind { kExtended, kExtendedWithCurvature, kBicycle };
  Residuals(const NeedleModel& n, const std::vector<Observation>& o, Kind kind)
      : Eigen::DenseFunctor<double>(kind == Kind::kExtended                ? 2
                                    : kind == Kind::kExtendedWithCurvature ? 3
                                                                           : 1,
                                    static_cast<int>(o.size())),
        needle(n),
        observed(o),
        kind_(kind) {
    // The model at each observation's depth, a depth above the entry read as 0; the integrator
    // wants distinct ascending depths, so each observation points at its own.
    for (const auto& p : o)
      depths.push_back(std::max(0.0, p.depth_mm));
    std::sort(depths.begin(), depths.end());
    depths.erase(std::unique(depths.begin(), depths.end()), depths.end());
    for (const auto& p : o) {
      at.push_back(static_cast<std::size_t>(
          std::lower_bound(depths.begin(), depths.end(), std::max(0.0, p.depth_mm)) -
          depths.begin()));
    }
  }

  void split(const InputType& x, NeedleModel& n, Tissue& t) const {
    n = needle;
    if (kind_ == Kind::kBicycle) {
      n.curvature_per_mm = x[0];
      return;
    }
    t = {x[0], x[1]};
    if (kind_ == Kind::kExtendedWithCurvature) n.curvature_per_mm = x[2];
  }

  int operator()(const InputType& x, ValueType& r) const {
    NeedleModel n;
    Tissue t;
    split(x, n, t);
    auto y = deflectionAtDepths(n, t, depths);
    for (Eigen::Index i = 0; i < r.size(); ++i) {
      // Outside the model's domain: a large, smooth-enough penalty pushes the search back.
      const auto k = static_cast<std::size_t>(i);
      r[i] = y ? (*y)[at[k]] - observed[k].deflection_mm : 1e3;
    }
    return 0;
  }

  NeedleModel needle;
  std::vector<Observation> observed;
  std::vector<double> depths;   // distinct, ascending, ≥ 0
  std::vector<std::size_t> at;  // observation i's index into depths
  Kind kind_;
};

struct Solved {
  Eigen::VectorXd x;
  Eigen::VectorXd residuals;
  Eigen::MatrixXd jacobian;
  int iterations = 0;
  bool converged = false;
};

Solved solve(Residuals& f, Eigen::VectorXd x) {
  Eigen::NumericalDiff<Residuals, Eigen::Central> diff(f);
  Eigen::LevenbergMarquardt<Eigen::NumericalDiff<Residuals, Eigen::Central>> lm(diff);
  lm.setXtol(1e-14);
  lm.setFtol(1e-14);
  lm.setGtol(0.0);
  lm.setMaxfev(4000);
  const auto status = lm.minimize(x);
  Solved out;
  out.converged = status == Eigen::LevenbergMarquardtSpace::RelativeReductionTooSmall ||
                  status == Eigen::LevenbergMarquardtSpace::RelativeErrorTooSmall ||
                  status == Eigen::LevenbergMarquardtSpace::RelativeErrorAndReductionTooSmall ||
                  status == Eigen::LevenbergMarquardtSpace::CosinusTooSmall ||
                  status == Eigen::LevenbergMarquardtSpace::FtolTooSmall ||
                  status == Eigen::LevenbergMarquardtSpace::XtolTooSmall ||
                  status == Eigen::LevenbergMarquardtSpace::GtolTooSmall;
  out.x = x;
  out.residuals.resize(f.values());
  f(x, out.residuals);
  out.jacobian.resize(f.values(), f.inputs());
  diff.df(x, out.jacobian);
  out.iterations = static_cast<int>(lm.iterations());
  return out;
}

}  // namespace

namespace {

// A measured path, in the order measured: noise within `tolerance_mm` is data; what no single
// insertion can produce is refused, naming the observation (1-based).
Status checkPath(const std::vector<Observation>& observed, double tolerance_mm) {
  if (!std::isfinite(tolerance_mm) || tolerance_mm < 0) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("depth noise tolerance {} mm must be finite and ≥ 0", tolerance_mm));
  }
  // A path listed from its deepest point back to the entry is still one path.
  const bool reversed = !observed.empty() && observed.back().depth_mm < observed.front().depth_mm;
  double deepest = -std::numeric_limits<double>::infinity();
  std::size_t deepest_at = 0;
  double shallowest = std::numeric_limits<double>::infinity();
  for (std::size_t n = 0; n < observed.size(); ++n) {
    const std::size_t i = reversed ? observed.size() - 1 - n : n;
    const auto& o = observed[i];
    if (!std::isfinite(o.depth_mm) || !std::isfinite(o.deflection_mm)) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("observation {}: depth {} mm and deflection {} mm must be "
                                   "finite",
                                   i + 1, o.depth_mm, o.deflection_mm));
    }
    if (o.depth_mm < -tolerance_mm) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("observation {}: depth {} mm lies above the entry point by "
                                   "more than the {} mm depth noise tolerance: not part of a path "
                                   "that starts at the entry",
                                   i + 1, o.depth_mm, tolerance_mm),
                       "not_a_path");
    }
    if (o.depth_mm < deepest - tolerance_mm) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("observation {}: depth {} mm is {:.3g} mm shallower than "
                                   "observation {} ({} mm){}, more than the {} mm depth noise "
                                   "tolerance: a needle's path only goes deeper, so this is not "
                                   "one path (two paths in one file, or the columns swapped?)",
                                   i + 1, o.depth_mm, deepest - o.depth_mm, deepest_at + 1, deepest,
                                   reversed ? " listed after it" : "", tolerance_mm),
                       "not_a_path");
    }
    if (o.depth_mm > deepest) {
      deepest = o.depth_mm;
      deepest_at = i;
    }
    shallowest = std::min(shallowest, o.depth_mm);
  }
  if (deepest - shallowest <= tolerance_mm) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("the observations span {:.3g} mm of depth, no more than the {} "
                                 "mm depth noise tolerance: not a path",
                                 deepest - shallowest, tolerance_mm),
                     "not_a_path");
  }
  return Ok{};
}

}  // namespace

Expected<TissueFit> fitTissue(const NeedleModel& needle, const std::vector<Observation>& observed,
                              const FitOptions& options) {
  const std::size_t p = options.fit_curvature ? 3 : 2;
  if (observed.size() <= p) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("{} observations for {} parameters; need more", observed.size(), p));
  }
  if (auto ok = checkPath(observed, options.depth_noise_mm); !ok) return ok.error();
  if (auto ok = checkInputs(needle, options.initial); !ok) {
    return makeError(ErrorCode::kInvalidArgument, "initial guess: " + ok.error().message);
  }

  Residuals extended(
      needle, observed,
      options.fit_curvature ? Residuals::Kind::kExtendedWithCurvature : Residuals::Kind::kExtended);
  Eigen::VectorXd x0(p);
  x0[0] = options.initial.lambda1;
  x0[1] = options.initial.lambda2;
  if (options.fit_curvature) x0[2] = needle.curvature_per_mm;
  const Solved fit = solve(extended, x0);
  if (!fit.converged) {
    return makeError(ErrorCode::kDegenerate,
                     fmt::format("the fit did not converge in {} iterations (λ1 = {:.4g}, λ2 = "
                                 "{:.4g}, RMS {:.3g} mm): the path does not determine the tissue",
                                 fit.iterations, fit.x[0], fit.x[1],
                                 std::sqrt(fit.residuals.squaredNorm() /
                                           static_cast<double>(fit.residuals.size()))),
                     "not_converged");
  }

  TissueFit out;
  out.tissue = {fit.x[0], fit.x[1]};
  out.curvature_per_mm = options.fit_curvature ? fit.x[2] : needle.curvature_per_mm;
  out.iterations = fit.iterations;
  NeedleModel fitted_needle = needle;
  fitted_needle.curvature_per_mm = out.curvature_per_mm;
  if (!checkAdmissible(fitted_needle, out.tissue).admissible) {
    return makeError(ErrorCode::kDegenerate, "the fit ended outside the admissible parameters",
                     "inadmissible");
  }
  const double n = static_cast<double>(observed.size());
  const double rss = fit.residuals.squaredNorm();
  out.rms_mm = std::sqrt(rss / n);
  out.max_error_mm = fit.residuals.cwiseAbs().maxCoeff();
  const double sigma2 = rss / (n - static_cast<double>(p));
  const Eigen::MatrixXd jtj = fit.jacobian.transpose() * fit.jacobian;
  const Eigen::MatrixXd cov = sigma2 * jtj.ldlt().solve(Eigen::MatrixXd::Identity(p, p));
  for (std::size_t i = 0; i < p; ++i)
    out.standard_errors.push_back(
        std::sqrt(std::max(0.0, cov(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i)))));
  out.correlation = cov(0, 1) / std::sqrt(cov(0, 0) * cov(1, 1));

  // The plain bicycle model on the same data: only its curvature is free.
  Residuals plain(needle, observed, Residuals::Kind::kBicycle);
  Eigen::VectorXd k0(1);
  k0[0] = needle.curvature_per_mm;
  const Solved bicycle = solve(plain, k0);
  out.bicycle_curvature_per_mm = bicycle.x[0];
  out.max_error_bicycle_mm = bicycle.residuals.cwiseAbs().maxCoeff();
  return out;
}

}  // namespace ignav::deflection
