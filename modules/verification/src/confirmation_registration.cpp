#include "ignav/verification/confirmation_registration.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace ignav::verification {
namespace {

// The localisation error (RMS, 3-D) that leaves this FRE when n markers are fitted by a transform
// of d degrees of freedom: ⟨FRE²⟩ = (1 − d/3n)·FLE²; no less than `floor_mm`.
double localisationFromFre(double fre_mm, std::size_t n, registration::TransformKind kind,
                           double floor_mm) {
  const double d = kind == registration::TransformKind::kRigid ? 6.0 : 7.0;
  const double share = 1.0 - d / (3.0 * static_cast<double>(n));
  const double fle = share > 0.0 && std::isfinite(fre_mm) ? fre_mm / std::sqrt(share) : 0.0;
  return std::max(fle, floor_mm);
}

}  // namespace

Expected<ConfirmationRegistration> registerConfirmation(
    const registration::Registration& planning, const std::vector<Eigen::Vector3d>& markers_lps_mm,
    const std::vector<Eigen::Vector3d>& model_robot_mm, registration::TransformKind kind,
    const registration::RegistrationLimits& limits, const ConfirmationLimits& confirmation) {
  if (markers_lps_mm.size() != model_robot_mm.size() || markers_lps_mm.empty()) {
    return Error{ErrorCode::kInvalidArgument,
                 fmt::format("the confirmation CT shows {} of the robot's {} markers: it cannot be "
                             "registered (is the robot in the scan?)",
                             markers_lps_mm.size(), model_robot_mm.size()),
                 "markers_missing"};
  }
  ConfirmationRegistration out;
  for (std::size_t i = 0; i < markers_lps_mm.size(); ++i) {
    if (!markers_lps_mm[i].allFinite()) {
      return Error{ErrorCode::kInvalidArgument,
                   fmt::format("marker {} of the confirmation CT is not finite", i + 1),
                   "non_finite"};
    }
  }
  // The new markers fitted to the robot: the registration if they moved, and in any case their
  // own FRE, which says how well they were found.
  auto fresh = registration::registerPoints(markers_lps_mm, model_robot_mm, kind, limits);
  if (!fresh) {
    return Error{fresh.error().code,
                 "the confirmation CT's markers do not register: " + fresh.error().message,
                 fresh.error().reason};
  }
  const bool comparable = planning.image_mm.size() == markers_lps_mm.size();
  if (comparable) {
    std::size_t worst = 0;
    for (std::size_t i = 0; i < markers_lps_mm.size(); ++i) {
      const double d = (markers_lps_mm[i] - planning.image_mm[i]).norm();
      if (d > out.marker_shift_mm) {
        out.marker_shift_mm = d;
        worst = i;
      }
    }
    if (out.marker_shift_mm > confirmation.max_shift_mm) {
      return Error{ErrorCode::kInvalidArgument,
                   fmt::format("marker {} lies {:.1f} mm from where the planning CT showed it "
                               "(at most {:.1f} mm): another patient, another frame of reference "
                               "or another series? Nothing was measured",
                               worst + 1, out.marker_shift_mm, confirmation.max_shift_mm),
                   "markers_far_off"};
    }
    out.planning_localisation_mm = localisationFromFre(
        planning.fre_mm, planning.image_mm.size(), planning.kind, confirmation.min_localisation_mm);
    out.confirmation_localisation_mm = localisationFromFre(fresh->fre_mm, markers_lps_mm.size(),
                                                           kind, confirmation.min_localisation_mm);
    out.reuse_limit_mm = confirmation.reuse_sigmas *
                         std::hypot(out.planning_localisation_mm, out.confirmation_localisation_mm);
    if (out.marker_shift_mm <= out.reuse_limit_mm) {
      out.reused = true;
      out.registration = planning;
      out.message = fmt::format(
          "the session's registration reused: the markers moved at most {:.3f} mm, within what "
          "their localisation explains ({:.3f} mm: {:g} × √({:.3f}² + {:.3f}²), each from its "
          "FRE)",
          out.marker_shift_mm, out.reuse_limit_mm, confirmation.reuse_sigmas,
          out.planning_localisation_mm, out.confirmation_localisation_mm);
      return out;
    }
  }
  out.registration = std::move(fresh).value();
  out.message =
      comparable
          ? fmt::format(
                "registered anew on the confirmation CT's markers: they moved up to {:.3f} mm, "
                "more than their localisation explains ({:.3f} mm: {:g} × √({:.3f}² + {:.3f}²), "
                "each from its FRE); FRE {:.3f} mm",
                out.marker_shift_mm, out.reuse_limit_mm, confirmation.reuse_sigmas,
                out.planning_localisation_mm, out.confirmation_localisation_mm,
                out.registration.fre_mm)
          : fmt::format(
                "registered on the confirmation CT's markers (the session's registration was "
                "given as a matrix): FRE {:.3f} mm",
                out.registration.fre_mm);
  return out;
}

Expected<ConfirmationRegistration> registerConfirmationByMatrix(
    const Eigen::Matrix4d& image_to_robot, const registration::RegistrationLimits& limits) {
  auto given = registration::registrationFromMatrix(image_to_robot, limits);
  if (!given) return given.error();
  ConfirmationRegistration out;
  out.by_matrix = true;
  out.marker_shift_mm = std::numeric_limits<double>::quiet_NaN();
  out.registration = std::move(given).value();
  out.message = fmt::format(
      "registered by the matrix given with the scan (scale {:.4f}): the markers were not "
      "compared",
      out.registration.scale);
  return out;
}

}  // namespace ignav::verification
