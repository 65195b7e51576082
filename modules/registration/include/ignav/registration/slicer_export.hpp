// Files 3D Slicer opens directly: the registration as an ITK text transform (.tfm) and points
// as Markups JSON (.mrk.json), both in LPS.
//
// ITK transform files hold the *resampling* direction, which Slicer reads as the node's
// transform FROM its parent: for a parent in image space and a child in robot space that is
// exactly our image -> robot map. So in Slicer: load the .tfm, put robot-frame data (the
// feasible volume, robot-frame points) under it, and they appear where they belong in the CT.
// Robot-frame coordinates are read as LPS, like every ITK file.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/registration/point_registration.hpp"

namespace ignav::registration {

// "#Insight Transform File V1.0" with one AffineTransform_double_3_3: Parameters are the 3×3
// matrix (scale included, row-major) then the translation; FixedParameters the centre (0).
std::string itkTransformText(const Registration& registration);
Status writeItkTransform(const Registration& registration, const std::string& path);

struct MarkupPoint {
  std::string label;  // shown next to the point in Slicer
  Eigen::Vector3d position_lps_mm = Eigen::Vector3d::Zero();
  std::string description;
  bool locked = true;
};

// One Fiducial (point list) markups node named `name` with coordinateSystem LPS.
std::string markupsJsonText(const std::string& name, const std::vector<MarkupPoint>& points);
Status writeMarkupsJson(const std::string& name, const std::vector<MarkupPoint>& points,
                        const std::string& path);

}  // namespace ignav::registration
