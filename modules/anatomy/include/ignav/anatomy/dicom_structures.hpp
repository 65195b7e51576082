// Structures from DICOM (issue 41): RT Structure Sets, as treatment planning systems export
// them (closed planar contours drawn on the CT's slices), and Segmentation objects (DICOM SEG),
// as AI segmenters write them (binary frames placed in the patient). Both are read onto the
// session's CT grid and must belong to its frame of reference. Values only; DCMTK does the
// parsing (dcmrt, dcmseg).
#pragma once

#include <string>
#include <vector>

#include "ignav/anatomy/structures.hpp"

namespace ignav::anatomy {

// One contour of an RT Structure Set, its points in LPS mm as the file lists them (the closing
// edge back to the first point is implied).
struct PlanarContour {
  std::vector<Eigen::Vector3d> points_lps_mm;
};

// Closed planar contours drawn on `ct`'s voxels: every contour must lie in one of the CT's
// slices (within 5 % of the slice spacing) and within its slices' range; each slice's contours
// are combined by the even-odd rule (a contour inside another is a hole; DICOM RT draws holes so,
// as dicompyler-core and plastimatch read them); a voxel is inside when its centre is.
// The mask returned is cropped to the structure. Errors name `what` and the contour (from 1):
// fewer than three distinct points or coordinates not finite (format), a contour crossing itself
// (self_intersecting, with the point), a contour off the CT's slices or beyond them (other_ct),
// no voxel centre enclosed (empty_structure).
Expected<Mask> rasteriseContours(const std::vector<PlanarContour>& contours,
                                 const volume::Geometry& ct, const std::string& what);

// An RT Structure Set (Modality RTSTRUCT): every ROI with closed planar contours becomes a
// structure (its ROIName, ROIDisplayColor; RTROIInterpretedType PTV, CTV or GTV a target,
// AVOIDANCE avoided, before the site's roles), rasterised on the CT; ROIs of points or open
// contours only (isocentres, markers) and ROIs without contours are listed in the set's notes. An
// ROI whose ReferencedFrameOfReferenceUID differs from the CT's is refused (other_ct); a CT without
// one (NRRD, MetaImage) is checked by geometry alone, which the notes say.
Expected<StructureSet> readRtStructureSet(const std::string& path, const CtFrame& ct);

// A DICOM Segmentation (Modality SEG), binary or fractional (a voxel is inside from half the
// maximum): each segment's frames placed by their ImagePositionPatient on the CT's slices, named
// by SegmentLabel, coloured from RecommendedDisplayCIELabValue. Frames must lie on the CT's
// voxels with its orientation and spacing (other_ct), as must the frame of reference.
Expected<StructureSet> readDicomSeg(const std::string& path, const CtFrame& ct);

// What an RT Structure Set written for a CT says of it: the series its contours were drawn on,
// the study and patient they belong to (the CT's, when known).
struct RtStructureSetHeader {
  std::string label = "ignav";  // StructureSetLabel
  std::string patient_name, patient_id;
  std::string study_uid;              // "" -> a new one
  std::string referenced_series_uid;  // the CT's SeriesInstanceUID ("" -> not referenced)
  std::string sop_instance_uid;       // "" -> a new one (an RT Plan may name it beforehand)
};

// Every structure of `set` as an ROI of closed planar contours on `ct`'s slices: each slice's
// voxels traced (OpenCV's border following, holes as inner contours) a quarter voxel outside
// their centres, so that rasteriseContours draws the same voxels again. ROIs in the CT's frame of
// reference, coloured as the structures, their roles as RT ROI Interpreted Types (target ->
// PTV, avoid -> AVOIDANCE, shown -> ORGAN).
Status writeRtStructureSet(const StructureSet& set, const CtFrame& ct,
                           const RtStructureSetHeader& header, const std::string& path);

// Either of the above, by the file's Modality; another DICOM object is refused (unsupported).
Expected<StructureSet> readDicomStructures(const std::string& path, const CtFrame& ct);

}  // namespace ignav::anatomy
