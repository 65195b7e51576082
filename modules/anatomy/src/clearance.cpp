// The whole needle's closest approach to a structure (clearance.hpp).
#include "ignav/anatomy/clearance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ignav::anatomy {
namespace {

// Trilinear interpolation of a distance field may change a little faster than the distance: a
// stride is shortened by this factor.
constexpr double kSlope = 1.5;

struct Polyline {
  const std::vector<Eigen::Vector3d>& p;
  std::vector<double> arc;  // cumulative
  explicit Polyline(const std::vector<Eigen::Vector3d>& points) : p(points) {
    arc.resize(p.size(), 0.0);
    for (std::size_t i = 1; i < p.size(); ++i)
      arc[i] = arc[i - 1] + (p[i] - p[i - 1]).norm();
  }
  double length() const { return arc.empty() ? 0.0 : arc.back(); }
  Eigen::Vector3d at(double s) const {
    if (p.size() == 1) return p.front();
    const auto it = std::upper_bound(arc.begin(), arc.end(), s);
    const std::size_t i =
        std::clamp<std::size_t>(static_cast<std::size_t>(it - arc.begin()), 1, p.size() - 1);
    const double span = arc[i] - arc[i - 1];
    const double t = span > 0.0 ? std::clamp((s - arc[i - 1]) / span, 0.0, 1.0) : 0.0;
    return p[i - 1] + t * (p[i] - p[i - 1]);
  }
};

}  // namespace

ClosestApproach closestApproach(const NeedleBody& body, const DistanceField& field,
                                double step_mm) {
  ClosestApproach best;
  const double step = std::max(step_mm, 1e-3);
  // A first bound on the closest approach, from a sample every few millimetres of every piece:
  // the strides below are measured from it, so a long stretch that runs parallel to the
  // structure, farther than another piece comes, is crossed in strides rather than steps.
  constexpr double kBoundSpacing_mm = 2.0;
  double bound = std::numeric_limits<double>::infinity();
  for (const auto& pc : body) {
    if (pc.centreline_lps_mm.empty()) continue;
    const Polyline line(pc.centreline_lps_mm);
    for (double s = 0.0;; s += kBoundSpacing_mm) {
      bound = std::min(bound, field.at(line.at(std::min(s, line.length()))) - pc.radius_mm);
      if (s >= line.length()) break;
    }
  }
  double arc_before = 0.0;
  for (std::size_t piece = 0; piece < body.size(); ++piece) {
    const auto& pc = body[piece];
    if (pc.centreline_lps_mm.empty()) continue;
    const Polyline line(pc.centreline_lps_mm);
    const double length = line.length();
    auto clearance = [&](double s) { return field.at(line.at(s)) - pc.radius_mm; };
    double best_s = 0.0, best_d = clearance(0.0);
    for (double s = 0.0;;) {
      const double d = clearance(s);
      if (d < best_d) best_d = d, best_s = s;
      if (s >= length) break;
      // Nothing before the next sample comes closer than the closest yet (of this piece, or the
      // bound): this piece's closest is found as finely only where it is the body's.
      s = std::min(length, s + std::max(step, (d - std::min(best_d, bound)) / kSlope));
    }
    // Golden section about the closest sample.
    double lo = std::max(0.0, best_s - step), hi = std::min(length, best_s + step);
    const double r = 0.5 * (std::sqrt(5.0) - 1.0);
    double x1 = hi - r * (hi - lo), x2 = lo + r * (hi - lo);
    double f1 = clearance(x1), f2 = clearance(x2);
    for (int it = 0; it < 40 && hi - lo > 1e-5; ++it) {
      if (f1 < f2) {
        hi = x2, x2 = x1, f2 = f1;
        x1 = hi - r * (hi - lo), f1 = clearance(x1);
      } else {
        lo = x1, x1 = x2, f1 = f2;
        x2 = lo + r * (hi - lo), f2 = clearance(x2);
      }
    }
    for (const double s : {x1, x2}) {
      const double d = clearance(s);
      if (d < best_d) best_d = d, best_s = s;
    }
    if (best_d < best.distance_mm) {
      best.distance_mm = best_d;
      best.needle_lps_mm = line.at(best_s);
      best.piece = piece;
      best.arc_mm = arc_before + best_s;
      best.structure_lps_mm =
          best.needle_lps_mm - field.gradient(best.needle_lps_mm) * field.at(best.needle_lps_mm);
    }
    arc_before += length;
  }
  return best;
}

bool staysFarther(const NeedleBody& body, const DistanceField& field, double distance_mm,
                  double step_mm) {
  const double step = std::max(step_mm, 1e-3);
  for (const auto& pc : body) {
    if (pc.centreline_lps_mm.empty()) continue;
    const Polyline line(pc.centreline_lps_mm);
    const double length = line.length();
    for (double s = 0.0;;) {
      // Within a step of it: the strides could no longer vouch for what lies between.
      const double above = field.at(line.at(s)) - pc.radius_mm - distance_mm;
      if (above < step * kSlope) return false;
      if (s >= length) break;
      s = std::min(length, s + above / kSlope);
    }
  }
  return true;
}

}  // namespace ignav::anatomy
