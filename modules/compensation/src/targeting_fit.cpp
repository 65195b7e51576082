// The tissue fitted from measured targeting errors (docs/COMPENSATION.md): Levenberg–Marquardt on
// the 3-D residuals between where each seed ended and where the model says its joints land.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include <fmt/format.h>

#include <Eigen/Dense>
#include <unsupported/Eigen/LevenbergMarquardt>

#include "ignav/compensation/compensation.hpp"
#include "polyline.hpp"

namespace ignav::compensation {
namespace {

// Outside the model's domain (inadmissible, turned back): a large residual pushes the search back.
constexpr double kPenalty_mm = 1e3;
// The scaled Jacobian's condition number beyond which the records do not determine the parameters.
constexpr double kMaxCondition = 1e7;

enum class Kind { kExtended, kExtendedWithCurvature, kBicycle };

int parameterCount(Kind kind) {
  return kind == Kind::kExtended ? 2 : kind == Kind::kExtendedWithCurvature ? 3 : 1;
}

// The predicted path is sampled this finely: its chords sag 0.1² / (8 · 35.5) = 35 nm off the
// stylet's arc, far below a CT's localisation. It reaches this far above the tissue (a CT shows
// the cannula up to the robot).
constexpr double kPathStep_mm = 0.1;
constexpr double kPathAbove_mm = 40.0;

// A measured centreline's errors are correlated along it (the detection refines each point over a
// 3 mm window, and its bias varies slowly): points closer than this are not independent
// observations, and counted as such a dense path would outweigh every landing with its bias.
constexpr double kPathSpacing_mm = 5.0;
// ... and a centreline point is known less well than a landing: the detection's centreline lies
// within 0.15 mm of the needle where a tip or a seed is localised to 0.05 mm
// (docs/VERIFICATION.md), so its offsets are weighed by the ratio (least squares weighs each
// residual by 1/σ).
constexpr double kPathWeight = 0.05 / 0.15;

// The records with each path thinned to points kPathSpacing_mm apart along it, from its deep end
// (the tip, where the tissue shows most).
std::vector<TargetingRecord> withIndependentPathPoints(std::vector<TargetingRecord> records) {
  for (auto& r : records)
    r.path_mm = detail::thinnedFromTip(r.path_mm, kPathSpacing_mm);
  return records;
}

int pathPoints(const std::vector<TargetingRecord>& records) {
  std::size_t n = 0;
  for (const auto& r : records)
    n += r.path_mm.size();
  return static_cast<int>(n);
}

struct Residuals : Eigen::DenseFunctor<double> {
  Residuals(const kinematics::Kinematics& k, const DeflectionModel& m,
            const std::vector<TargetingRecord>& r, Kind kind)
      : Eigen::DenseFunctor<double>(parameterCount(kind),
                                    3 * (static_cast<int>(r.size()) + pathPoints(r))),
        kinematics(k),
        model(m),
        records(r),
        kind_(kind) {}

  DeflectionModel modelAt(const InputType& x) const {
    DeflectionModel m = model;
    if (kind_ == Kind::kBicycle) {
      m.tissue = {};
      m.needle.curvature_per_mm = x[0];
      return m;
    }
    m.tissue = {x[0], x[1]};
    if (kind_ == Kind::kExtendedWithCurvature) m.needle.curvature_per_mm = x[2];
    return m;
  }

  // False (and the penalty in r) where the model does not hold for the parameters x.
  bool evaluate(const InputType& x, ValueType& r) const {
    const DeflectionModel m = modelAt(x);
    r.resize(values());
    bool inside = true;
    for (std::size_t i = 0; i < records.size(); ++i) {
      auto landing = predictLanding(kinematics, m, records[i].joints);
      inside = inside && landing.ok();
      const Eigen::Vector3d e = landing ? Eigen::Vector3d(landing->tip_mm - records[i].actual_mm)
                                        : Eigen::Vector3d::Constant(kPenalty_mm);
      r.segment<3>(3 * static_cast<Eigen::Index>(i)) = e;
    }
    // The paths after the landings, so that the landings' errors stay the first 3n values.
    Eigen::Index at = 3 * static_cast<Eigen::Index>(records.size());
    for (const auto& record : records) {
      if (record.path_mm.empty()) continue;
      auto path = predictPath(kinematics, m, record.joints, kPathStep_mm, kPathAbove_mm);
      inside = inside && path.ok();
      std::vector<Eigen::Vector3d> line;
      if (path) {
        line = path->cannula_mm;
        line.insert(line.end(), path->stylet_mm.begin(), path->stylet_mm.end());
      }
      for (const auto& q : record.path_mm) {
        r.segment<3>(at) =
            path ? Eigen::Vector3d(kPathWeight * (detail::nearestOnPolyline(line, q) - q))
                 : Eigen::Vector3d::Constant(kPenalty_mm);
        at += 3;
      }
    }
    return inside;
  }

  int operator()(const InputType& x, ValueType& r) const {
    evaluate(x, r);
    return 0;
  }

  // Central differences with steps of 1e-6 relative (far above the integrator's 1e-12 noise);
  // one-sided where a step would leave the model's admissible parameters, so that a fit resting
  // on that limit still sees the slope on its own side.
  int df(const InputType& x, JacobianType& jac) const {
    jac.resize(values(), inputs());
    ValueType plus, minus, centre;
    evaluate(x, centre);
    for (Eigen::Index j = 0; j < x.size(); ++j) {
      const double h = 1e-6 * std::max(std::abs(x[j]), typical(j));
      InputType xp = x, xm = x;
      xp[j] += h;
      xm[j] -= h;
      const bool p_ok = evaluate(xp, plus), m_ok = evaluate(xm, minus);
      if (p_ok && m_ok) {
        jac.col(j) = (plus - minus) / (2.0 * h);
      } else if (p_ok || m_ok) {
        jac.col(j) = p_ok ? ValueType((plus - centre) / h) : ValueType((centre - minus) / h);
      } else {
        jac.col(j).setZero();
      }
    }
    return 0;
  }

  // Which parameter, if any, rests on the admissibility limit at x, and why.
  std::string limitAt(const InputType& x) const {
    for (Eigen::Index j = 0; j < x.size(); ++j) {
      const double h = 1e-5 * std::max(std::abs(x[j]), typical(j));
      for (double side : {1.0, -1.0}) {
        InputType beyond = x;
        beyond[j] += side * h;
        const DeflectionModel m = modelAt(beyond);
        if (auto ok = deflection::checkAdmissible(m.needle, m.tissue); !ok.admissible) {
          return fmt::format(
              "{} = {:.4g} rests on the model's admissibility limit (just {} it, {}): the "
              "errors would take it further, so it is bounded there rather than determined, and "
              "its standard error is one-sided",
              name(j), x[j], side > 0 ? "above" : "below", ok.reason);
        }
      }
    }
    return {};
  }

  double typical(Eigen::Index j) const {
    const bool curvature = kind_ == Kind::kBicycle || j == 2;
    return curvature ? 1e-3 : 0.1;
  }
  const char* name(Eigen::Index j) const {
    return kind_ == Kind::kBicycle || j == 2 ? "k" : j == 0 ? "λ1" : "λ2";
  }

  const kinematics::Kinematics& kinematics;
  DeflectionModel model;
  const std::vector<TargetingRecord>& records;
  Kind kind_;
};

struct Solved {
  Eigen::VectorXd x, residuals;
  Eigen::MatrixXd jacobian;
  int iterations = 0;
  bool converged = false;
};

Eigen::MatrixXd jacobianAt(const Residuals& f, const Eigen::VectorXd& x) {
  Eigen::MatrixXd j;
  f.df(x, j);
  return j;
}

// The condition number of the Jacobian with unit columns: how well the data separate the
// parameters, whatever their units.
double condition(const Eigen::MatrixXd& j) {
  Eigen::MatrixXd scaled = j;
  for (Eigen::Index c = 0; c < j.cols(); ++c) {
    const double n = j.col(c).norm();
    if (!(n > 0.0)) return std::numeric_limits<double>::infinity();
    scaled.col(c) /= n;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(scaled);
  const auto& s = svd.singularValues();
  return s[s.size() - 1] > 0.0 ? s[0] / s[s.size() - 1] : std::numeric_limits<double>::infinity();
}

Solved solve(Residuals& f, Eigen::VectorXd x, int max_evaluations) {
  Eigen::LevenbergMarquardt<Residuals> lm(f);
  lm.setXtol(1e-14);
  lm.setFtol(1e-14);
  lm.setGtol(0.0);
  lm.setMaxfev(max_evaluations);
  const auto status = lm.minimize(x);
  using namespace Eigen::LevenbergMarquardtSpace;
  Solved out;
  out.converged = status == RelativeReductionTooSmall || status == RelativeErrorTooSmall ||
                  status == RelativeErrorAndReductionTooSmall || status == CosinusTooSmall ||
                  status == FtolTooSmall || status == XtolTooSmall || status == GtolTooSmall;
  out.x = x;
  f.evaluate(x, out.residuals);
  out.jacobian = jacobianAt(f, x);
  out.iterations = static_cast<int>(lm.iterations());
  return out;
}

// Per-target 3-D error norms of a residual vector (its first 3 × targets values: the landings).
std::vector<double> norms(const Eigen::VectorXd& r, std::size_t targets) {
  std::vector<double> out;
  const auto end = std::min<Eigen::Index>(r.size(), 3 * static_cast<Eigen::Index>(targets));
  for (Eigen::Index i = 0; i + 2 < end; i += 3)
    out.push_back(r.segment<3>(i).norm());
  return out;
}

double rms(const std::vector<double>& e) {
  double s = 0.0;
  for (double v : e)
    s += v * v;
  return std::sqrt(s / static_cast<double>(e.size()));
}

struct Start {
  Eigen::VectorXd x;
  std::string what;
  double rss = 0.0;  // the sum of squares there
};

// Where the search may start, lowest sum of squares first: the guess, the plain model the extended
// one extends (λ = 0; with k fitted too, at the plain fit's curvature) and every point of the grid.
std::vector<Start> startsFor(const Residuals& f, const Eigen::VectorXd& guess, double bicycle_k,
                             const TargetingFitOptions& options) {
  Eigen::VectorXd plain = guess;
  plain[0] = plain[1] = 0.0;
  if (options.fit_curvature) plain[2] = bicycle_k;
  std::vector<Start> out;
  Eigen::VectorXd r;
  auto consider = [&](const Eigen::VectorXd& x, std::string what) {
    if (f.evaluate(x, r)) out.push_back({x, std::move(what), r.squaredNorm()});
  };
  consider(guess, "the guess");
  consider(plain, "the plain model");
  for (const auto& t : deflection::tissueGrid(f.model.needle)) {
    Eigen::VectorXd x = guess;
    x[0] = t.lambda1;
    x[1] = t.lambda2;
    consider(x, fmt::format("grid ({:.2f}, {:.2f})", t.lambda1, t.lambda2));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const Start& a, const Start& b) { return a.rss < b.rss; });
  return out;
}

}  // namespace

Expected<TargetingFit> fitTissueFromTargeting(const kinematics::Kinematics& kinematics,
                                              const DeflectionModel& model,
                                              const std::vector<TargetingRecord>& observed,
                                              const TargetingFitOptions& options) {
  const Kind kind = options.fit_curvature ? Kind::kExtendedWithCurvature : Kind::kExtended;
  const int p = parameterCount(kind);
  const std::vector<TargetingRecord> records = withIndependentPathPoints(observed);
  // Each target gives two in-plane residuals that the tissue moves (and one across, noise only);
  // a visible path as many again per independent point.
  const auto observations = 2 * (records.size() + static_cast<std::size_t>(pathPoints(records)));
  if (observations <= static_cast<std::size_t>(p)) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("{} targets for {} parameters: need at least {}", records.size(), p, p / 2 + 1),
        "underdetermined");
  }
  double deepest = 0.0, shallowest = std::numeric_limits<double>::infinity();
  for (const auto& r : observed) {  // every path point checked, not only those the fit keeps
    const auto& j = r.joints;
    const bool path_finite = std::all_of(r.path_mm.begin(), r.path_mm.end(),
                                         [](const Eigen::Vector3d& q) { return q.allFinite(); });
    if (!r.planned_mm.allFinite() || !r.actual_mm.allFinite() || !path_finite ||
        !std::isfinite(j.theta_c_rad) || !std::isfinite(j.z_c_mm) || !std::isfinite(j.z_s_mm)) {
      return makeError(
          ErrorCode::kInvalidArgument,
          fmt::format("target '{}': planned, actual, path and joints must be finite", r.id));
    }
    if (auto ok = kinematics.checkJoints(j); !ok) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("target '{}': {}", r.id, ok.error().message));
    }
    deepest = std::max(deepest, j.z_c_mm);
    shallowest = std::min(shallowest, j.z_c_mm);
  }
  if (!(deepest > 0.0)) {
    return makeError(ErrorCode::kInvalidArgument,
                     "no target was reached with the cannula in tissue (every z_c is 0): the "
                     "errors say nothing about the tissue",
                     "underdetermined");
  }
  if (auto ok = deflection::checkAdmissible(model.needle, options.initial); !ok.admissible) {
    return makeError(ErrorCode::kInvalidArgument, "initial guess: " + ok.reason);
  }

  Residuals extended(kinematics, model, records, kind);
  Eigen::VectorXd x0(p);
  x0[0] = options.initial.lambda1;
  x0[1] = options.initial.lambda2;
  if (options.fit_curvature) x0[2] = model.needle.curvature_per_mm;
  auto underdetermined = [&](double cond) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("the {} targets do not determine λ1, λ2{} (condition number {:.3g}): their "
                    "insertions span z_c {:.1f}–{:.1f} mm; targets at several depths, the deeper "
                    "the better, separate the parameters",
                    records.size(), options.fit_curvature ? " and k" : "", cond, shallowest,
                    deepest),
        "underdetermined");
  };
  if (const double c = condition(jacobianAt(extended, x0)); !(c < kMaxCondition)) {
    return underdetermined(c);
  }

  // The plain bicycle model on the same errors (its curvature free): for comparison, and where k
  // is fitted too, the start that makes the extended fit at least as good as it.
  Residuals plain(kinematics, model, records, Kind::kBicycle);
  Eigen::VectorXd k0(1);
  k0[0] = model.needle.curvature_per_mm;
  const Solved bicycle = solve(plain, k0, options.max_evaluations);

  // LM from the lowest start, then from the next ones while they lie below the best end so far
  // (one above it is unlikely to descend past it), at most grid_starts + 2 runs. The plain model
  // is among the starts and LM only descends: the fit ends no worse than it.
  const auto starts = startsFor(extended, x0, bicycle.x[0], options);
  const auto max_runs = static_cast<std::size_t>(std::max(options.grid_starts, 0)) + 2;
  std::optional<Solved> fit;
  std::string won;
  std::size_t runs = 0;
  for (const auto& start : starts) {
    if (runs == max_runs) break;
    if (fit && fit->converged && !(start.rss < fit->residuals.squaredNorm())) break;
    Solved run = solve(extended, start.x, options.max_evaluations);
    ++runs;
    // A converged end beats one that is not; among equals, the lower sum of squares.
    const bool better = !fit || (run.converged && !fit->converged) ||
                        (run.converged == fit->converged &&
                         run.residuals.squaredNorm() < fit->residuals.squaredNorm());
    if (better) {
      fit = std::move(run);
      won = start.what;
    }
  }
  if (!fit) {
    return makeError(ErrorCode::kDegenerate,
                     "no start of the fit lies where the model holds (every one inadmissible)",
                     "not_converged");
  }
  if (!fit->converged) {
    return makeError(
        ErrorCode::kDegenerate,
        fmt::format("the fit did not converge from any of {} starts (from {}: {} iterations, "
                    "λ1 = {:.4g}, λ2 = {:.4g}, RMS {:.3g} mm)",
                    runs, won, fit->iterations, fit->x[0], fit->x[1],
                    rms(norms(fit->residuals, records.size()))),
        "not_converged");
  }
  if (const double c = condition(fit->jacobian); !(c < kMaxCondition)) return underdetermined(c);

  TargetingFit out;
  out.limit = extended.limitAt(fit->x);
  out.tissue = {fit->x[0], fit->x[1]};
  out.curvature_per_mm = options.fit_curvature ? fit->x[2] : model.needle.curvature_per_mm;
  out.iterations = fit->iterations;
  out.starts = static_cast<int>(runs);
  out.start = won;
  deflection::NeedleModel fitted = model.needle;
  fitted.curvature_per_mm = out.curvature_per_mm;
  if (auto ok = deflection::checkAdmissible(fitted, out.tissue); !ok.admissible) {
    return makeError(ErrorCode::kDegenerate,
                     fmt::format("the fit ended outside the model's admissible parameters "
                                 "(λ1 = {:.4g}, λ2 = {:.4g}): {}",
                                 out.tissue.lambda1, out.tissue.lambda2, ok.reason),
                     "inadmissible");
  }
  const auto errors = norms(fit->residuals, records.size());
  out.rms_mm = rms(errors);
  out.max_error_mm = *std::max_element(errors.begin(), errors.end());
  const double dof = static_cast<double>(fit->residuals.size() - p);
  const double sigma2 = fit->residuals.squaredNorm() / dof;
  const Eigen::MatrixXd cov =
      sigma2 *
      (fit->jacobian.transpose() * fit->jacobian).ldlt().solve(Eigen::MatrixXd::Identity(p, p));
  for (Eigen::Index i = 0; i < p; ++i)
    out.standard_errors.push_back(std::sqrt(std::max(0.0, cov(i, i))));
  out.correlation = cov(0, 1) / std::sqrt(cov(0, 0) * cov(1, 1));

  const auto bicycle_errors = norms(bicycle.residuals, records.size());
  out.bicycle_curvature_per_mm = bicycle.x[0];
  out.rms_bicycle_mm = rms(bicycle_errors);
  out.max_error_bicycle_mm = *std::max_element(bicycle_errors.begin(), bicycle_errors.end());
  std::vector<double> measured, deflection, spread;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const auto& r = records[i];
    const Eigen::Vector3d nominal = kinematics.forward(r.joints).tip_mm;
    const auto at = 3 * static_cast<Eigen::Index>(i);
    const Eigen::Vector3d landing = r.actual_mm + fit->residuals.segment<3>(at);
    const Eigen::MatrixXd j = fit->jacobian.middleRows(at, 3);  // d landing / d parameters
    measured.push_back((r.actual_mm - nominal).norm());
    deflection.push_back((landing - nominal).norm());
    spread.push_back(std::sqrt(std::max(0.0, (j * cov * j.transpose()).trace())));
  }
  out.rms_no_deflection_mm = rms(measured);
  out.predicted_deflection_mm = rms(deflection);
  out.prediction_se_mm = rms(spread);
  const std::string figures = fmt::format(
      "λ1 = {:.3g} ± {:.3g}, λ2 = {:.3g} ± {:.3g}; RMS {:.3f} mm fitted, {:.3f} mm with no "
      "deflection, {:.3f} mm for the plain bicycle model",
      out.tissue.lambda1, out.standard_errors[0], out.tissue.lambda2, out.standard_errors[1],
      out.rms_mm, out.rms_no_deflection_mm, out.rms_bicycle_mm);
  if (!(out.rms_mm < out.rms_no_deflection_mm)) {
    return makeError(ErrorCode::kDegenerate,
                     fmt::format("the fitted tissue explains the {} targets' errors no better than "
                                 "no deflection at all ({}): the errors are not the model's "
                                 "deflection (noise, motion, or another cause); not offered for "
                                 "aiming",
                                 records.size(), figures),
                     "explains_nothing");
  }
  if (!(out.prediction_se_mm <= options.max_prediction_uncertainty * out.predicted_deflection_mm)) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("the {} targets do not determine the tissue: the landings it "
                    "predicts are uncertain by ±{:.3f} mm (1 SE from the parameters' "
                    "covariance, RMS over the targets), more than {:g} of the {:.3f} "
                    "mm of deflection it predicts ({}); not offered for aiming",
                    records.size(), out.prediction_se_mm, options.max_prediction_uncertainty,
                    out.predicted_deflection_mm, figures),
        "underdetermined");
  }
  return out;
}

Expected<std::string> tissueProfileYaml(const std::string& name, const TargetingFit& fit,
                                        const std::string& source, bool with_curvature) {
  const bool plain = !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
  });
  if (!plain) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("tissue name '{}': use letters, digits, '_' and '-' only", name));
  }
  std::string out = fmt::format("  {}:\n    lambda1: {}\n    lambda2: {}\n", name,
                                fit.tissue.lambda1, fit.tissue.lambda2);
  if (with_curvature) out += fmt::format("    curvature_per_mm: {}\n", fit.curvature_per_mm);
  std::string note = source;
  std::replace(note.begin(), note.end(), '\n', ' ');
  std::replace(note.begin(), note.end(), '"', '\'');
  std::replace(note.begin(), note.end(), '\\', '/');
  const auto& se = fit.standard_errors;
  out += fmt::format(
      "    source: \"{}; ±{:.2g} / ±{:.2g} (1 SE), RMS {:.3g} mm (plain bicycle {:.3g} mm)\"\n",
      note, se.size() > 0 ? se[0] : 0.0, se.size() > 1 ? se[1] : 0.0, fit.rms_mm,
      fit.rms_bicycle_mm);
  return out;
}

}  // namespace ignav::compensation
