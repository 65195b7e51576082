#include "ignav/verification/confirmation_registration.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace ignav::verification {

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
  const bool comparable = planning.image_mm.size() == markers_lps_mm.size();
  if (comparable) {
    std::size_t worst = 0;
    for (std::size_t i = 0; i < markers_lps_mm.size(); ++i) {
      const double d = (markers_lps_mm[i] - planning.image_mm[i]).norm();
      if (!std::isfinite(d)) {
        return Error{ErrorCode::kInvalidArgument,
                     fmt::format("marker {} of the confirmation CT is not finite", i + 1),
                     "non_finite"};
      }
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
    if (out.marker_shift_mm <= confirmation.reuse_within_mm) {
      out.reused = true;
      out.registration = planning;
      out.message = fmt::format(
          "the session's registration reused: the markers moved at most {:.2f} mm (≤ {:.2f})",
          out.marker_shift_mm, confirmation.reuse_within_mm);
      return out;
    }
  }
  auto fresh = registration::registerPoints(markers_lps_mm, model_robot_mm, kind, limits);
  if (!fresh) {
    return Error{fresh.error().code,
                 "the confirmation CT's markers do not register: " + fresh.error().message,
                 fresh.error().reason};
  }
  out.registration = std::move(fresh).value();
  out.message = comparable
                    ? fmt::format(
                          "registered anew on the confirmation CT's markers (they moved up to "
                          "{:.2f} mm): FRE {:.3f} mm",
                          out.marker_shift_mm, out.registration.fre_mm)
                    : fmt::format(
                          "registered on the confirmation CT's markers (the session's "
                          "registration was given as a matrix): FRE {:.3f} mm",
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
