// The seeds as a DICOM RT Plan (issue 42, part 5): a permanent interstitial implant (RT Brachy
// Application Setups), for 3D Slicer (SlicerRT), treatment planning systems and the records of
// what was planned or implanted: one source (the seed model and its strength), one channel per
// seed holding its position.
#pragma once

#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/dosimetry/dose_grid.hpp"
#include "ignav/dosimetry/tg43.hpp"

namespace ignav::dosimetry {

struct RtPlanHeader {
  std::string sop_instance_uid;        // "" -> a new one (an RT Dose may name it beforehand)
  std::string frame_of_reference_uid;  // the CT's ("" -> a new one)
  std::string study_uid;               // "" -> a new one
  std::string patient_name, patient_id;
  std::string label = "ignav seeds";       // RTPlanLabel (16 characters at most are kept)
  std::string structure_set_uid;           // the RT Structure Set the plan refers to ("" -> none)
  std::string approach = "PERINEAL";       // ApplicationSetupType
  std::string date_yyyymmdd, time_hhmmss;  // the source strength's reference ("" -> none)
};

// `seeds` of `model`, each of air-kerma strength `strength_U` (ReferenceAirKermaRate, µGy h⁻¹ at
// 1 m), prescribed `prescription_Gy` (the target's, in the fraction group's dose reference).
// Refused (bad_plan): no seeds, more than 9999, a seed not finite, a strength or prescription not
// positive; a file that cannot be written (naming it).
Status writeSeedRtPlan(const std::vector<Seed>& seeds, const SeedModel& model, double strength_U,
                       double prescription_Gy, const RtPlanHeader& header, const std::string& path);

// A new DICOM UID (DCMTK's, under its root): for objects that refer to each other before they
// are written.
std::string newDicomUid();

}  // namespace ignav::dosimetry
