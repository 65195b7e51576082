// The confirmation CT's registration (issue 23, step 1): the robot's markers found on the new
// scan are compared with those the session registered on. Within `reuse_within_mm` of them the
// session's registration is reused (the robot and the scanner did not move); farther, but within
// `max_shift_mm`, the scan is registered anew from its own markers; farther still, or without
// markers, it is refused: another patient, another frame, or the wrong series.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/registration/point_registration.hpp"

namespace ignav::verification {

struct ConfirmationLimits {
  double reuse_within_mm = 1.0;  // the paper's markers are localised to a few tenths of a mm
  double max_shift_mm = 20.0;
};

struct ConfirmationRegistration {
  bool reused = false;           // the session's registration, else one from the new markers
  double marker_shift_mm = 0.0;  // the largest move of a marker (LPS) since the planning CT
  bool by_matrix = false;        // given with the scan: no markers compared (shift NaN)
  registration::Registration registration;
  std::string message;  // for a person: reused or re-registered, the shift, the FRE
};

// `planning`: the session's registration (its image_mm are the markers it was made from, in the
// model's order; a registration given as a matrix has none: then the scan is registered anew).
// `markers_lps_mm`: the markers found on the confirmation CT, in the model's order.
// `model_robot_mm`: the robot's feature points. Errors name the marker and the distance.
Expected<ConfirmationRegistration> registerConfirmation(
    const registration::Registration& planning, const std::vector<Eigen::Vector3d>& markers_lps_mm,
    const std::vector<Eigen::Vector3d>& model_robot_mm, registration::TransformKind kind,
    const registration::RegistrationLimits& limits, const ConfirmationLimits& confirmation = {});

// The scan registered by a transform given with it (the session's own, or one computed elsewhere,
// e.g. the confirmation CT registered to the planning CT in 3D Slicer), where its markers cannot
// serve: a needle left in touches those on its axis (the paper's feature points are the
// needle's own), or the scan leaves the robot out. Checked as set_registration checks a matrix.
Expected<ConfirmationRegistration> registerConfirmationByMatrix(
    const Eigen::Matrix4d& image_to_robot, const registration::RegistrationLimits& limits);

}  // namespace ignav::verification
