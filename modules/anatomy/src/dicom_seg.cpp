// DICOM Segmentations on the CT's voxels, and which DICOM reader a file needs
// (dicom_structures.hpp).
#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmfg/fgpixmsr.h>
#include <dcmtk/dcmfg/fgplanor.h>
#include <dcmtk/dcmfg/fgplanpo.h>
#include <dcmtk/dcmfg/fgseg.h>
#include <dcmtk/dcmiod/cielabutil.h>
#include <dcmtk/dcmseg/segdoc.h>
#include <dcmtk/dcmseg/segment.h>
#include <dcmtk/dcmseg/segutils.h>
#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <string_view>

#include "ignav/anatomy/dicom_structures.hpp"

namespace ignav::anatomy {
namespace {

// The loaded file: DcmSegmentation keeps pointers into the dataset it was read from.
struct SegFile {
  DcmFileFormat file;
  std::unique_ptr<DcmSegmentation> seg;
};

}  // namespace

Expected<StructureSet> readDicomSeg(const std::string& path, const CtFrame& ct) {
  auto refuse = [&](const std::string& how, const char* reason) {
    return makeError(ErrorCode::kFormat, path + ": " + how, reason);
  };
  auto other_ct = [&](const std::string& how) {
    return makeError(
        ErrorCode::kInvalidArgument,
        fmt::format("{}: the segmentation was not made on this CT ({}): {}", path, ct.name, how),
        "other_ct");
  };
  SegFile in;
  if (OFCondition c = in.file.loadFile(path.c_str()); c.bad()) {
    return makeError(ErrorCode::kIo, path + ": cannot read as DICOM: " + c.text(), "format");
  }
  DcmDataset& ds = *in.file.getDataset();
  Uint16 rows = 0, cols = 0, max_fraction = 0;
  ds.findAndGetUint16(DCM_Rows, rows);
  ds.findAndGetUint16(DCM_Columns, cols);
  {
    DcmSegmentation* loaded = nullptr;
    if (OFCondition c = DcmSegmentation::loadDataset(ds, loaded); c.bad() || loaded == nullptr) {
      return refuse(std::string("not a DICOM Segmentation DCMTK reads: ") + c.text(), "format");
    }
    in.seg.reset(loaded);
  }
  DcmSegmentation& seg = *in.seg;
  const bool binary = seg.getSegmentationType() == DcmSegTypes::ST_BINARY;
  if (!binary) {
    if (seg.getSegmentationType() != DcmSegTypes::ST_FRACTIONAL) {
      return refuse("a segmentation neither binary nor fractional", "unsupported");
    }
    ds.findAndGetUint16(DCM_MaximumFractionalValue, max_fraction);
    if (max_fraction == 0) return refuse("MaximumFractionalValue (0062,000E) missing", "format");
  }
  if (rows == 0 || cols == 0) return refuse("Rows or Columns missing", "format");

  // Frame of reference, then the frames' geometry against the CT's.
  OFString frame;
  seg.getFrameOfReference().getFrameOfReferenceUID(frame);
  StructureSet set;
  set.source = path;
  if (!ct.frame_of_reference_uid.empty() && !frame.empty() &&
      std::string(frame.c_str()) != ct.frame_of_reference_uid) {
    return other_ct(fmt::format("its frame of reference is {}, the CT's {}", frame.c_str(),
                                ct.frame_of_reference_uid));
  }
  if (ct.frame_of_reference_uid.empty() || frame.empty()) {
    set.notes.push_back(
        "frame of reference not checked: " +
        std::string(frame.empty() ? "the segmentation names none" : "the CT's files carry none") +
        "; its voxels' places were");
  }
  const volume::Geometry& g = ct.geometry;
  if (cols != g.dims[0] || rows != g.dims[1]) {
    return other_ct(fmt::format("its frames are {} x {} pixels, the CT's slices {} x {}", cols,
                                rows, g.dims[0], g.dims[1]));
  }
  FGInterface& groups = seg.getFunctionalGroups();
  const std::size_t frames = seg.getNumberOfFrames();
  std::vector<std::vector<std::uint8_t>> inside(seg.getNumberOfSegments());
  for (std::size_t f = 0; f < frames; ++f) {
    const auto frame_no = static_cast<Uint32>(f);
    auto* orientation = dynamic_cast<FGPlaneOrientationPatient*>(
        groups.get(frame_no, DcmFGTypes::EFG_PLANEORIENTPATIENT));
    auto* measures =
        dynamic_cast<FGPixelMeasures*>(groups.get(frame_no, DcmFGTypes::EFG_PIXELMEASURES));
    auto* position =
        dynamic_cast<FGPlanePosPatient*>(groups.get(frame_no, DcmFGTypes::EFG_PLANEPOSPATIENT));
    auto* segment =
        dynamic_cast<FGSegmentation*>(groups.get(frame_no, DcmFGTypes::EFG_SEGMENTATION));
    if (!orientation || !measures || !position || !segment) {
      return refuse(fmt::format("frame {} lacks its orientation, pixel measures, position or "
                                "segment number",
                                f + 1),
                    "format");
    }
    Float64 iop[6] = {}, ipp[3] = {}, spacing[2] = {};
    Uint16 number = 0;
    if (orientation->getImageOrientationPatient(iop[0], iop[1], iop[2], iop[3], iop[4], iop[5])
            .bad() ||
        position->getImagePositionPatient(ipp[0], ipp[1], ipp[2]).bad() ||
        measures->getPixelSpacing(spacing[0], 0).bad() ||
        measures->getPixelSpacing(spacing[1], 1).bad() ||
        segment->getReferencedSegmentNumber(number).bad() || number == 0 ||
        number > inside.size()) {
      return refuse(fmt::format("frame {}: orientation, position, pixel spacing or segment number "
                                "unreadable or out of range",
                                f + 1),
                    "format");
    }
    const Eigen::Vector3d row(iop[0], iop[1], iop[2]), col(iop[3], iop[4], iop[5]);
    if ((row - g.direction.col(0)).norm() > 1e-4 || (col - g.direction.col(1)).norm() > 1e-4) {
      return other_ct(fmt::format("frame {} is oriented otherwise than the CT's slices", f + 1));
    }
    // PixelSpacing is [between rows, between columns]: the CT's j then i.
    if (std::abs(spacing[1] - g.spacing_mm.x()) > 1e-3 * g.spacing_mm.x() ||
        std::abs(spacing[0] - g.spacing_mm.y()) > 1e-3 * g.spacing_mm.y()) {
      return other_ct(
          fmt::format("frame {}'s pixels measure {:.4g} x {:.4g} mm, the CT's {:.4g} x "
                      "{:.4g} mm",
                      f + 1, spacing[1], spacing[0], g.spacing_mm.x(), g.spacing_mm.y()));
    }
    const Eigen::Vector3d ijk = g.toIjk(Eigen::Vector3d(ipp[0], ipp[1], ipp[2]));
    const int k = static_cast<int>(std::lround(ijk.z()));
    if (std::abs(ijk.x()) > 0.01 || std::abs(ijk.y()) > 0.01 || std::abs(ijk.z() - k) > 0.01 ||
        k < 0 || k >= g.dims[2]) {
      return other_ct(
          fmt::format("frame {} at ({:.2f}, {:.2f}, {:.2f}) mm LPS is not one of the "
                      "CT's slices (it falls at voxel {:.2f}, {:.2f}, {:.2f})",
                      f + 1, ipp[0], ipp[1], ipp[2], ijk.x(), ijk.y(), ijk.z()));
    }
    const DcmIODTypes::Frame* stored = seg.getFrame(f);
    if (stored == nullptr) return refuse(fmt::format("frame {} has no pixels", f + 1), "format");
    std::unique_ptr<DcmIODTypes::Frame> unpacked;
    const DcmIODTypes::Frame* pixels = stored;
    if (binary) {
      unpacked.reset(DcmSegUtils::unpackBinaryFrame(stored, rows, cols));
      pixels = unpacked.get();
    }
    const std::size_t plane = static_cast<std::size_t>(rows) * cols;
    if (pixels == nullptr || pixels->length < plane) {
      return refuse(fmt::format("frame {} holds fewer pixels than {} x {}", f + 1, cols, rows),
                    "format");
    }
    auto& mask = inside[number - 1u];
    if (mask.empty()) mask.assign(g.voxelCount(), 0);
    const std::size_t at = plane * static_cast<std::size_t>(k);
    for (std::size_t p = 0; p < plane; ++p) {
      const unsigned v = pixels->pixData[p];
      if (binary ? v != 0 : 2u * v >= max_fraction) mask[at + p] = 1;
    }
  }

  for (std::size_t n = 0; n < inside.size(); ++n) {
    DcmSegment* segment = seg.getSegment(n + 1);
    OFString label;
    if (segment == nullptr || segment->getSegmentLabel(label).bad() || label.empty()) {
      return refuse(fmt::format("segment {} has no label (SegmentLabel 0062,0005)", n + 1),
                    "names_missing");
    }
    const std::string name = label.c_str();
    if (set.find(name))
      return refuse(fmt::format("two segments are labelled '{}'", name), "format");
    if (inside[n].empty()) {
      return makeError(
          ErrorCode::kFormat,
          fmt::format("{}: segment '{}': the structure is empty (no frame)", path, name),
          "empty_structure");
    }
    auto mask = cropMask(g, inside[n], fmt::format("{}: segment '{}'", path, name));
    if (!mask) return mask.error();
    Structure s;
    s.name = name;
    Uint16 lab[3] = {};
    if (segment->getRecommendedDisplayCIELabValue(lab[0], lab[1], lab[2]).good()) {
      double r = 0, gr = 0, b = 0;
      IODCIELabUtil::dicomLab2RGB(r, gr, b, lab[0], lab[1], lab[2]);
      s.colour_rgb = {std::clamp(r, 0.0, 1.0), std::clamp(gr, 0.0, 1.0), std::clamp(b, 0.0, 1.0)};
    }
    s.mask = std::move(mask).value();
    set.structures.push_back(std::move(s));
  }
  if (set.structures.empty()) return refuse("the segmentation holds no segment", "empty_structure");
  return set;
}

namespace {

// A DICOM file: the "DICM" prefix after its preamble, or (written without the file meta
// header, as older systems and pydicom's rtstruct.dcm are) a first element of group 0008.
bool looksLikeDicom(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char head[132] = {};
  in.read(head, sizeof head);
  const auto got = in.gcount();
  if (got == 132 && std::string_view(head + 128, 4) == "DICM") return true;
  return got >= 4 && head[0] == 0x08 && head[1] == 0x00;
}

}  // namespace

Expected<StructureSet> readDicomStructures(const std::string& path, const CtFrame& ct) {
  auto unsupported = [&](const std::string& why) {
    return makeError(ErrorCode::kUnsupported,
                     fmt::format("{}: not a segmentation ignav reads (.seg.nrrd, a .nrrd/.nhdr/"
                                 ".mha/.mhd label map with a colour table, a DICOM RT Structure "
                                 "Set or DICOM SEG): {}",
                                 path, why),
                     "unsupported");
  };
  // Anything else DCMTK would try to parse as a bare dataset, logging its confusion.
  if (!looksLikeDicom(path)) return unsupported("neither of these, nor DICOM");
  DcmFileFormat file;
  // Large values (pixel data) stay on disk until asked for: the reader chosen reads them.
  if (OFCondition c = file.loadFile(path.c_str()); c.bad()) return unsupported(c.text());
  OFString modality;
  file.getDataset()->findAndGetOFString(DCM_Modality, modality);
  if (modality == "RTSTRUCT") return readRtStructureSet(path, ct);
  if (modality == "SEG") return readDicomSeg(path, ct);
  return makeError(ErrorCode::kUnsupported,
                   fmt::format("{}: a DICOM {} object, not an RT Structure Set (RTSTRUCT) or a "
                               "Segmentation (SEG)",
                               path, modality.empty() ? "(no Modality)" : modality.c_str()),
                   "unsupported");
}

}  // namespace ignav::anatomy
