// Structures as an RT Structure Set: each slice's voxels traced into contours
// (dicom_structures.hpp).
#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <fmt/format.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "ignav/anatomy/dicom_structures.hpp"

namespace ignav::anatomy {
namespace {

std::string newUid() {
  char uid[100];
  dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT);
  return uid;
}

const char* interpretedType(Role role) {
  switch (role) {
    case Role::kTarget:
      return "PTV";
    case Role::kAvoid:
      return "AVOIDANCE";
    case Role::kShown:
      return "ORGAN";
  }
  return "ORGAN";
}

// The contours of one slice of `mask`, as LPS points. The slice is traced at twice its
// resolution: the border pixels' centres then lie a quarter voxel outside the voxels' centres
// (inside their cells), so centres inside stay inside and the neighbours' stay out.
std::vector<std::vector<Eigen::Vector3d>> sliceContours(const Mask& mask, int k) {
  const auto& d = mask.geometry.dims;
  cv::Mat fine(2 * d[1] + 2, 2 * d[0] + 2, CV_8U, cv::Scalar(0));  // a pixel's frame of zeros
  for (int j = 0; j < d[1]; ++j)
    for (int i = 0; i < d[0]; ++i)
      if (mask.inside[mask.index(i, j, k)]) {
        fine(cv::Rect(2 * i + 1, 2 * j + 1, 2, 2)).setTo(255);
      }
  std::vector<std::vector<cv::Point>> traced;
  std::vector<cv::Vec4i> hierarchy;
  // Two levels: outer borders and the borders of their holes (islands in holes are outer again).
  cv::findContours(fine, traced, hierarchy, cv::RETR_CCOMP, cv::CHAIN_APPROX_SIMPLE);
  std::vector<std::vector<Eigen::Vector3d>> out;
  for (const auto& contour : traced) {
    std::vector<Eigen::Vector3d> lps;
    lps.reserve(contour.size());
    // Fine pixel u (after the frame) is centred at voxel coordinate (u - 1) / 2 - 0.25.
    for (const auto& p : contour)
      lps.push_back(
          mask.geometry.toLps(Eigen::Vector3d(0.5 * (p.x - 1) - 0.25, 0.5 * (p.y - 1) - 0.25, k)));
    out.push_back(std::move(lps));
  }
  return out;
}

std::string decimalString(const std::vector<Eigen::Vector3d>& points) {
  std::string out;
  out.reserve(points.size() * 30);
  for (const auto& p : points)
    for (int a = 0; a < 3; ++a)
      out += fmt::format("{}{:.4f}", out.empty() ? "" : "\\", p[a]);
  return out;
}

}  // namespace

Status writeRtStructureSet(const StructureSet& set, const CtFrame& ct,
                           const RtStructureSetHeader& header, const std::string& path) {
  if (auto on_ct = checkOnCt(set, ct.geometry, ct.name); !on_ct.ok()) return on_ct.error();
  if (set.structures.empty()) {
    return makeError(ErrorCode::kInvalidArgument, path + ": no structure to write");
  }
  DcmFileFormat file;
  DcmDataset& ds = *file.getDataset();
  OFCondition c = EC_Normal;
  auto put = [&c](DcmItem& item, const DcmTagKey& tag, const std::string& value) {
    if (c.good()) c = item.putAndInsertString(tag, value.c_str());
  };
  auto append = [&c](DcmItem& parent, const DcmTagKey& sequence) -> DcmItem* {
    DcmItem* item = nullptr;
    if (c.good()) c = parent.findOrCreateSequenceItem(sequence, item, -2);
    return c.good() ? item : nullptr;
  };
  const std::string frame =
      ct.frame_of_reference_uid.empty() ? newUid() : ct.frame_of_reference_uid;
  const std::string study = header.study_uid.empty() ? newUid() : header.study_uid;
  put(ds, DCM_SOPClassUID, UID_RTStructureSetStorage);
  put(ds, DCM_SOPInstanceUID, header.sop_instance_uid.empty() ? newUid() : header.sop_instance_uid);
  put(ds, DCM_Modality, "RTSTRUCT");
  put(ds, DCM_Manufacturer, "ignav");
  put(ds, DCM_PatientName, header.patient_name);
  put(ds, DCM_PatientID, header.patient_id);
  put(ds, DCM_StudyInstanceUID, study);
  put(ds, DCM_SeriesInstanceUID, newUid());
  put(ds, DCM_SeriesNumber, "1");
  put(ds, DCM_StructureSetLabel, header.label);
  if (DcmItem* ref = append(ds, DCM_ReferencedFrameOfReferenceSequence)) {
    put(*ref, DCM_FrameOfReferenceUID, frame);
    if (!header.referenced_series_uid.empty()) {
      if (DcmItem* st = append(*ref, DCM_RTReferencedStudySequence)) {
        put(*st, DCM_ReferencedSOPClassUID, UID_RETIRED_StudyComponentManagementSOPClass);
        put(*st, DCM_ReferencedSOPInstanceUID, study);
        if (DcmItem* se = append(*st, DCM_RTReferencedSeriesSequence)) {
          put(*se, DCM_SeriesInstanceUID, header.referenced_series_uid);
        }
      }
    }
  }
  for (std::size_t n = 0; n < set.structures.size() && c.good(); ++n) {
    const Structure& s = set.structures[n];
    const std::string number = std::to_string(n + 1);
    if (DcmItem* roi = append(ds, DCM_StructureSetROISequence)) {
      put(*roi, DCM_ROINumber, number);
      put(*roi, DCM_ReferencedFrameOfReferenceUID, frame);
      put(*roi, DCM_ROIName, s.name);
      put(*roi, DCM_ROIGenerationAlgorithm, "SEMIAUTOMATIC");
    }
    if (DcmItem* rc = append(ds, DCM_ROIContourSequence)) {
      put(*rc, DCM_ReferencedROINumber, number);
      put(*rc, DCM_ROIDisplayColor,
          fmt::format("{}\\{}\\{}", std::lround(s.colour_rgb[0] * 255),
                      std::lround(s.colour_rgb[1] * 255), std::lround(s.colour_rgb[2] * 255)));
      int contour_number = 0;
      for (int k = 0; k < s.mask.geometry.dims[2] && c.good(); ++k) {
        for (const auto& points : sliceContours(s.mask, k)) {
          DcmItem* contour = append(*rc, DCM_ContourSequence);
          if (contour == nullptr) break;
          put(*contour, DCM_ContourNumber, std::to_string(++contour_number));
          put(*contour, DCM_ContourGeometricType, "CLOSED_PLANAR");
          put(*contour, DCM_NumberOfContourPoints, std::to_string(points.size()));
          put(*contour, DCM_ContourData, decimalString(points));
        }
      }
    }
    if (DcmItem* obs = append(ds, DCM_RTROIObservationsSequence)) {
      put(*obs, DCM_ObservationNumber, number);
      put(*obs, DCM_ReferencedROINumber, number);
      put(*obs, DCM_RTROIInterpretedType, interpretedType(s.role));
      put(*obs, DCM_ROIInterpreter, "");
    }
  }
  if (c.good()) c = file.saveFile(path.c_str(), EXS_LittleEndianExplicit);
  if (c.bad())
    return makeError(ErrorCode::kIo, path + ": cannot write the RT Structure Set: " + c.text());
  return Ok{};
}

}  // namespace ignav::anatomy
