// The seeds as an RT Plan (rt_plan.hpp).
#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>

#include <cmath>

#include <fmt/format.h>

#include "ignav/dosimetry/rt_plan.hpp"

namespace ignav::dosimetry {

std::string newDicomUid() {
  char uid[100];
  dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT);
  return uid;
}

namespace {

// Puts strings into one item (the dataset or a sequence's item), keeping the first failure.
struct Writer {
  OFCondition& c;
  DcmItem& item;
  void operator()(const DcmTagKey& tag, const std::string& value) const {
    if (c.good()) c = item.putAndInsertString(tag, value.c_str());
  }
  // A new item at the end of `sequence` (created when absent); nullptr after a failure.
  Writer add(const DcmTagKey& sequence) const {
    DcmItem* next = nullptr;
    if (c.good()) c = item.findOrCreateSequenceItem(sequence, next, -2);
    if (c.good() && next == nullptr) c = EC_MemoryExhausted;
    return Writer{c, c.good() ? *next : item};
  }
};

std::string decimal(double v) {
  return fmt::format("{:.6g}", v);
}

}  // namespace

Status writeSeedRtPlan(const std::vector<Seed>& seeds, const SeedModel& model, double strength_U,
                       double prescription_Gy, const RtPlanHeader& header,
                       const std::string& path) {
  auto bad = [&](const std::string& why) {
    return makeError(ErrorCode::kInvalidArgument, path + ": " + why, "bad_plan");
  };
  if (seeds.empty()) return bad("no seeds to write");
  if (seeds.size() > 9999) return bad(fmt::format("{} seeds, more than 9999", seeds.size()));
  for (std::size_t n = 0; n < seeds.size(); ++n) {
    if (!seeds[n].centre_lps_mm.allFinite() || !seeds[n].axis_lps.allFinite())
      return bad(fmt::format("seed {} is not at a finite position", n + 1));
  }
  if (!(strength_U > 0.0) || !std::isfinite(strength_U))
    return bad(fmt::format("a strength of {} U is not one", strength_U));
  if (!(prescription_Gy > 0.0) || !std::isfinite(prescription_Gy))
    return bad(fmt::format("a prescription of {} Gy is not one", prescription_Gy));

  DcmFileFormat file;
  OFCondition c = EC_Normal;
  const Writer put{c, *file.getDataset()};
  put(DCM_SOPClassUID, UID_RTPlanStorage);
  put(DCM_SOPInstanceUID,
      header.sop_instance_uid.empty() ? newDicomUid() : header.sop_instance_uid);
  put(DCM_Modality, "RTPLAN");
  put(DCM_Manufacturer, "ignav");
  put(DCM_PatientName, header.patient_name);
  put(DCM_PatientID, header.patient_id);
  put(DCM_PatientBirthDate, "");
  put(DCM_PatientSex, "");
  put(DCM_StudyInstanceUID, header.study_uid.empty() ? newDicomUid() : header.study_uid);
  put(DCM_StudyDate, "");
  put(DCM_StudyTime, "");
  put(DCM_StudyID, "");
  put(DCM_AccessionNumber, "");
  put(DCM_ReferringPhysicianName, "");
  put(DCM_SeriesInstanceUID, newDicomUid());
  put(DCM_SeriesNumber, "1");
  put(DCM_InstanceNumber, "1");
  put(DCM_OperatorsName, "");
  put(DCM_FrameOfReferenceUID,
      header.frame_of_reference_uid.empty() ? newDicomUid() : header.frame_of_reference_uid);
  put(DCM_PositionReferenceIndicator, "");
  // RT General Plan: the seeds are in the patient's coordinates (the CT's frame).
  put(DCM_RTPlanLabel, header.label.substr(0, 16));
  put(DCM_RTPlanDate, header.date_yyyymmdd);
  put(DCM_RTPlanTime, header.time_hhmmss);
  put(DCM_RTPlanGeometry, header.structure_set_uid.empty() ? "TREATMENT_DEVICE" : "PATIENT");
  if (!header.structure_set_uid.empty()) {
    const Writer ss = put.add(DCM_ReferencedStructureSetSequence);
    ss(DCM_ReferencedSOPClassUID, UID_RTStructureSetStorage);
    ss(DCM_ReferencedSOPInstanceUID, header.structure_set_uid);
  }
  put(DCM_ApprovalStatus, "UNAPPROVED");
  // The prescription, to the target.
  const Writer reference = put.add(DCM_DoseReferenceSequence);
  reference(DCM_DoseReferenceNumber, "1");
  reference(DCM_DoseReferenceStructureType, "SITE");
  reference(DCM_DoseReferenceDescription, "target");
  reference(DCM_DoseReferenceType, "TARGET");
  reference(DCM_TargetPrescriptionDose, decimal(prescription_Gy));
  const Writer fraction = put.add(DCM_FractionGroupSequence);
  fraction(DCM_FractionGroupNumber, "1");
  fraction(DCM_NumberOfFractionsPlanned, "1");
  fraction(DCM_NumberOfBeams, "0");
  fraction(DCM_NumberOfBrachyApplicationSetups, "1");
  fraction.add(DCM_ReferencedBrachyApplicationSetupSequence)(
      DCM_ReferencedBrachyApplicationSetupNumber, "1");
  // RT Brachy Application Setups: a permanent low-dose-rate implant of one seed model.
  put(DCM_BrachyTreatmentTechnique, "PERMANENT");
  put(DCM_BrachyTreatmentType, "LDR");
  const Writer machine = put.add(DCM_TreatmentMachineSequence);
  machine(DCM_TreatmentMachineName, "ignav seed robot");
  machine(DCM_Manufacturer, "ignav");
  const double half_life_days = model.half_life_h / 24.0;
  const Writer source = put.add(DCM_SourceSequence);
  source(DCM_SourceNumber, "1");
  source(DCM_SourceType, "LINE");
  source(DCM_SourceManufacturer, "");
  source(DCM_SourceModelID, model.name);
  source(DCM_ActiveSourceLength, decimal(10.0 * model.active_length_cm));
  source(DCM_SourceIsotopeName, model.isotope);
  source(DCM_SourceIsotopeHalfLife, decimal(half_life_days));
  source(DCM_SourceStrengthUnits, "AIR_KERMA_RATE");
  source(DCM_SourceStrength, decimal(strength_U));
  source(DCM_ReferenceAirKermaRate, decimal(strength_U));  // U = µGy m² h⁻¹: µGy h⁻¹ at 1 m
  source(DCM_SourceStrengthReferenceDate, header.date_yyyymmdd);
  source(DCM_SourceStrengthReferenceTime, header.time_hhmmss);
  // A permanent seed delivers its initial rate for its mean life, T½ / ln 2.
  const double mean_life_h = model.half_life_h / std::log(2.0);
  const Writer setup = put.add(DCM_ApplicationSetupSequence);
  setup(DCM_ApplicationSetupType, header.approach);
  setup(DCM_ApplicationSetupNumber, "1");
  setup(DCM_TotalReferenceAirKerma,
        decimal(strength_U * mean_life_h * static_cast<double>(seeds.size())));
  for (std::size_t n = 0; n < seeds.size(); ++n) {
    const Writer channel = setup.add(DCM_ChannelSequence);
    channel(DCM_ChannelNumber, std::to_string(n + 1));
    channel(DCM_ChannelLength, "");
    channel(DCM_ChannelTotalTime, decimal(3600.0 * mean_life_h));
    channel(DCM_SourceMovementType, "FIXED");
    channel(DCM_NumberOfControlPoints, "2");
    channel(DCM_ReferencedSourceNumber, "1");
    channel(DCM_TransferTubeNumber, "");
    channel(DCM_FinalCumulativeTimeWeight, "1");
    const Eigen::Vector3d& p = seeds[n].centre_lps_mm;
    const std::string position = fmt::format("{:.4f}\\{:.4f}\\{:.4f}", p.x(), p.y(), p.z());
    for (int index = 0; index < 2; ++index) {
      const Writer point = channel.add(DCM_BrachyControlPointSequence);
      point(DCM_ControlPointIndex, std::to_string(index));
      point(DCM_CumulativeTimeWeight, std::to_string(index));
      point(DCM_ControlPointRelativePosition, "0");
      point(DCM_ControlPoint3DPosition, position);
    }
  }
  if (c.good()) c = file.saveFile(path.c_str(), EXS_LittleEndianExplicit);
  if (c.bad()) return makeError(ErrorCode::kIo, path + ": cannot write the RT Plan: " + c.text());
  return Ok{};
}

}  // namespace ignav::dosimetry
