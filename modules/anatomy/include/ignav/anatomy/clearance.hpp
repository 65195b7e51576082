// The whole needle against a structure (issue 41): the cannula's straight and deflected part and
// the stylet's arc, each with its outer radius, and how close their surface comes to the
// structure's.
#pragma once

#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "ignav/anatomy/distance_field.hpp"

namespace ignav::anatomy {

// A polyline of constant outer radius (the cannula, then the stylet).
struct NeedlePiece {
  std::vector<Eigen::Vector3d> centreline_lps_mm;
  double radius_mm = 0.0;
};
using NeedleBody = std::vector<NeedlePiece>;

struct ClosestApproach {
  // From the needle's surface to the structure's: negative when the needle enters it (by that
  // depth). +inf for an empty body.
  double distance_mm = std::numeric_limits<double>::infinity();
  Eigen::Vector3d needle_lps_mm = Eigen::Vector3d::Zero();     // on the centreline
  Eigen::Vector3d structure_lps_mm = Eigen::Vector3d::Zero();  // the nearest surface point
  std::size_t piece = 0;                                       // which piece
  double arc_mm = 0.0;                                         // along the body from its start
};

// The closest approach: the centreline sampled at most `step_mm` apart where it comes near the
// structure (strides as long as the distance allows where it is far), then the closest sample
// refined by golden section along the polyline. The distance field is 1-Lipschitz, so the strides
// skip nothing closer than what was found.
ClosestApproach closestApproach(const NeedleBody& body, const DistanceField& field,
                                double step_mm = 0.1);

// Whether the needle's surface stays at least `distance_mm` from the structure everywhere: the
// same strides, as long as the distance above `distance_mm` allows (sphere tracing), so a body
// far from it costs a few samples where the closest approach measures every `step_mm` near its
// best. True says for certain that nothing comes closer; false that a sample came within
// `step_mm` of that distance or closer (an empty body stays far).
bool staysFarther(const NeedleBody& body, const DistanceField& field, double distance_mm,
                  double step_mm = 0.1);

// The uncertainty a clearance is judged with, where the needle passes closest: the expected
// registration error there (an RMS over three directions: per direction TRE/√3) and the aim's
// landing spread likewise, two standard deviations along the way to the structure, plus a drift
// the tissue predicts and the aim leaves uncompensated (it shifts the whole path).
inline double clearanceUncertainty_mm(double tre_mm, double landing_se_mm, double drift_mm) {
  return 2.0 * std::sqrt((tre_mm * tre_mm + landing_se_mm * landing_se_mm) / 3.0) + drift_mm;
}

}  // namespace ignav::anatomy
