// The confirmation CT's registration (issue 23, step 1): the robot's markers found on the new
// scan are compared with those the session registered on. While no marker moved by more than
// their localisation can explain, the session's registration is reused (the robot and the scanner
// did not move); farther, but within `max_shift_mm`, the scan is registered anew from its own
// markers; farther still, or without markers, it is refused: another patient, another frame, or
// the wrong series.
//
// How far localisation reaches (issue 40): each scan's markers say it themselves. Fitting them to
// the robot's model leaves a residual (FRE) that only their localisation error (FLE) makes, since
// the motion is rigid: ⟨FRE²⟩ = (1 − d/3N)·⟨FLE²⟩ for N markers and a transform of d degrees of
// freedom (Fitzpatrick et al. 1998; d = 6 rigid, 7 with scale). The planning markers' FLE and the
// new ones' add in quadrature for a marker's difference; a move beyond `reuse_sigmas` of it is
// motion. A common motion leaves the FRE unchanged, so even 0.8 mm is seen on markers found to
// 0.05 mm. Three markers estimate the FLE coarsely: it is taken as at least
// `min_localisation_mm`.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/registration/point_registration.hpp"

namespace ignav::verification {

struct ConfirmationLimits {
  double reuse_sigmas = 3.0;
  double min_localisation_mm = 0.05;  // our markers' localisation (docs/VERIFICATION.md)
  double max_shift_mm = 20.0;
};

struct ConfirmationRegistration {
  bool reused = false;           // the session's registration, else one from the new markers
  double marker_shift_mm = 0.0;  // the largest move of a marker (LPS) since the planning CT
  // The markers' localisation error (RMS, 3-D) from each registration's FRE, and the shift a
  // marker may show without having moved: reuse_sigmas × √(planning² + confirmation²).
  double planning_localisation_mm = 0.0;
  double confirmation_localisation_mm = 0.0;
  double reuse_limit_mm = 0.0;
  bool by_matrix = false;  // given with the scan: no markers compared (shift NaN)
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
