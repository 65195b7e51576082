// The dose as a DICOM RT Dose (issue 42, part 5), for 3D Slicer (SlicerRT), treatment planning
// systems and DVH tools: a dose grid on the CT's frame of reference, 32-bit with its scaling.
#pragma once

#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::dosimetry {

struct RtDoseHeader {
  std::string frame_of_reference_uid;  // the CT's ("" -> a new one, which no CT shares)
  std::string study_uid;               // "" -> a new one
  std::string patient_name, patient_id;
  std::string comment = "ignav TG-43U1";  // DoseComment
  std::string plan_uid;  // the RT Plan whose dose it is (ReferencedRTPlanSequence; "" -> none)
};

// `dose_Gy` at every voxel of `grid` (x fastest), as a multi-frame RT Dose (DoseUnits GY,
// PHYSICAL, PLAN summation). The grid's third axis must be the first two's cross product (frames
// stack along it, GridFrameOffsetVector); refused otherwise, or with doses that are not finite
// and non-negative, or a size that does not match.
Status writeRtDose(const std::vector<float>& dose_Gy, const volume::Geometry& grid,
                   const RtDoseHeader& header, const std::string& path);

}  // namespace ignav::dosimetry
