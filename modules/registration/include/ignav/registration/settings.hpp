// Everything a procedure configures about registration (robot YAML, `robot.registration`).
#pragma once

#include "ignav/registration/feature_points.hpp"
#include "ignav/registration/fiducial_detection.hpp"
#include "ignav/registration/point_registration.hpp"

namespace ignav::registration {

struct RegistrationSettings {
  ScanSetup scan;
  TransformKind kind = TransformKind::kSimilarity;
  RegistrationLimits limits;
  // Expected fiducial localisation error (RMS, 3-D) behind every TRE estimate: about half a
  // voxel diagonal for clicked points, less for detected beads.
  double fle_mm = 0.5;
  // A target whose expected TRE exceeds this carries a warning.
  double max_tre_mm = 2.0;
  FiducialSearch fiducials;
};

}  // namespace ignav::registration
