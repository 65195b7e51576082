// The dose as a DICOM RT Dose (rt_dose.hpp).
#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <fmt/format.h>
#include <Eigen/Geometry>

#include "ignav/dosimetry/rt_dose.hpp"
#include "ignav/dosimetry/rt_plan.hpp"

namespace ignav::dosimetry {
namespace {

std::string decimals(std::initializer_list<double> values) {
  std::string out;
  for (const double v : values)
    out += fmt::format("{}{:.6f}", out.empty() ? "" : "\\", v);
  return out;
}

}  // namespace

Status writeRtDose(const std::vector<float>& dose_Gy, const volume::Geometry& grid,
                   const RtDoseHeader& header, const std::string& path) {
  auto bad = [&](const std::string& why) {
    return makeError(ErrorCode::kInvalidArgument, path + ": " + why, "bad_dose");
  };
  if (auto ok = grid.validate(path); !ok.ok()) return ok.error();
  if (dose_Gy.size() != grid.voxelCount())
    return bad(fmt::format("{} doses for {} voxels", dose_Gy.size(), grid.voxelCount()));
  const Eigen::Vector3d normal = grid.direction.col(0).cross(grid.direction.col(1));
  if (normal.dot(grid.direction.col(2)) < 1.0 - 1e-6)
    return bad(
        "the grid's third axis is not its first two's cross product (RT Dose frames "
        "stack along it)");
  float max_Gy = 0.0f;
  for (std::size_t v = 0; v < dose_Gy.size(); ++v) {
    if (!std::isfinite(dose_Gy[v]) || dose_Gy[v] < 0.0f)
      return bad(fmt::format("voxel {}'s dose {} Gy is not a dose", v, dose_Gy[v]));
    max_Gy = std::max(max_Gy, dose_Gy[v]);
  }
  // Stored = round(dose / scaling), 32 bits: the largest dose at 4e9 counts.
  const double scaling = max_Gy > 0.0f ? static_cast<double>(max_Gy) / 4.0e9 : 1.0;
  std::vector<std::uint32_t> counts(dose_Gy.size());
  for (std::size_t v = 0; v < dose_Gy.size(); ++v)
    counts[v] = static_cast<std::uint32_t>(std::lround(static_cast<double>(dose_Gy[v]) / scaling));

  DcmFileFormat file;
  DcmDataset& ds = *file.getDataset();
  OFCondition c = EC_Normal;
  auto put = [&c, &ds](const DcmTagKey& tag, const std::string& value) {
    if (c.good()) c = ds.putAndInsertString(tag, value.c_str());
  };
  auto putNumber = [&c, &ds](const DcmTagKey& tag, Uint16 value) {
    if (c.good()) c = ds.putAndInsertUint16(tag, value);
  };
  const auto& d = grid.direction;
  const auto& s = grid.spacing_mm;
  const auto& o = grid.origin_lps_mm;
  put(DCM_SOPClassUID, UID_RTDoseStorage);
  put(DCM_SOPInstanceUID, newDicomUid());
  put(DCM_Modality, "RTDOSE");
  put(DCM_Manufacturer, "ignav");
  put(DCM_PatientName, header.patient_name);
  put(DCM_PatientID, header.patient_id);
  // Type 2 (present, may be empty), as the RT Dose IOD asks.
  for (const DcmTagKey& tag : {DCM_PatientBirthDate, DCM_PatientSex, DCM_StudyDate, DCM_StudyTime,
                               DCM_ReferringPhysicianName, DCM_StudyID, DCM_AccessionNumber,
                               DCM_OperatorsName, DCM_PositionReferenceIndicator})
    put(tag, "");
  put(DCM_StudyInstanceUID, header.study_uid.empty() ? newDicomUid() : header.study_uid);
  put(DCM_SeriesInstanceUID, newDicomUid());
  put(DCM_SeriesNumber, "1");
  put(DCM_InstanceNumber, "1");
  put(DCM_FrameOfReferenceUID,
      header.frame_of_reference_uid.empty() ? newDicomUid() : header.frame_of_reference_uid);
  put(DCM_ImagePositionPatient, decimals({o.x(), o.y(), o.z()}));
  put(DCM_ImageOrientationPatient,
      decimals({d(0, 0), d(1, 0), d(2, 0), d(0, 1), d(1, 1), d(2, 1)}));
  put(DCM_PixelSpacing, decimals({s.y(), s.x()}));  // rows apart, then columns apart
  put(DCM_SliceThickness, fmt::format("{:.6f}", s.z()));
  std::string offsets;
  for (int k = 0; k < grid.dims[2]; ++k)
    offsets += fmt::format("{}{:.6f}", k ? "\\" : "", k * s.z());
  put(DCM_GridFrameOffsetVector, offsets);
  if (c.good()) c = ds.putAndInsertTagKey(DCM_FrameIncrementPointer, DCM_GridFrameOffsetVector);
  put(DCM_NumberOfFrames, std::to_string(grid.dims[2]));
  putNumber(DCM_Rows, static_cast<Uint16>(grid.dims[1]));
  putNumber(DCM_Columns, static_cast<Uint16>(grid.dims[0]));
  putNumber(DCM_SamplesPerPixel, 1);
  put(DCM_PhotometricInterpretation, "MONOCHROME2");
  putNumber(DCM_BitsAllocated, 32);
  putNumber(DCM_BitsStored, 32);
  putNumber(DCM_HighBit, 31);
  putNumber(DCM_PixelRepresentation, 0);
  put(DCM_DoseUnits, "GY");
  put(DCM_DoseType, "PHYSICAL");
  put(DCM_DoseSummationType, "PLAN");
  if (!header.plan_uid.empty() && c.good()) {
    DcmItem* plan = nullptr;
    c = ds.findOrCreateSequenceItem(DCM_ReferencedRTPlanSequence, plan, -2);
    if (c.good()) c = plan->putAndInsertString(DCM_ReferencedSOPClassUID, UID_RTPlanStorage);
    if (c.good())
      c = plan->putAndInsertString(DCM_ReferencedSOPInstanceUID, header.plan_uid.c_str());
  }
  put(DCM_DoseComment, header.comment);
  put(DCM_DoseGridScaling, fmt::format("{:.10e}", scaling));
  if (c.good()) {
    // OW, as DICOM wants pixels of more than 8 bits: each 32-bit count as two 16-bit words, the
    // low one first (little endian, as the file is written).
    std::vector<Uint16> words(2 * counts.size());
    for (std::size_t v = 0; v < counts.size(); ++v) {
      words[2 * v] = static_cast<Uint16>(counts[v] & 0xffffu);
      words[2 * v + 1] = static_cast<Uint16>(counts[v] >> 16);
    }
    c = ds.putAndInsertUint16Array(DCM_PixelData, words.data(),
                                   static_cast<unsigned long>(words.size()));
  }
  if (c.good()) c = file.saveFile(path.c_str(), EXS_LittleEndianExplicit);
  if (c.bad()) return makeError(ErrorCode::kIo, path + ": cannot write the RT Dose: " + c.text());
  return Ok{};
}

}  // namespace ignav::dosimetry
