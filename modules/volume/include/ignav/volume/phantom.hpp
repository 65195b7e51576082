// The built-in phantom: a gelatin-like box in air with bright spherical fiducials and, for a
// confirmation scan, metal seeds (small cylinders), rendered with partial-volume edges; and a
// DICOM CT series writer (DCMTK) so the phantom is a real series that any DICOM reader opens.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::volume {

// A deposited seed (the paper's dummies, a brachytherapy seed): a solid metal cylinder with flat
// ends, centred on centre_lps_mm, its axis along axis_lps (need not be unit length).
struct PhantomSeed {
  Eigen::Vector3d centre_lps_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_lps = Eigen::Vector3d::UnitZ();
  double length_mm = 3.0;
  double diameter_mm = 0.8;
};

struct PhantomSpec {
  std::array<int, 3> dims{96, 96, 64};
  // A voxel averages its whole cell, so spacing_mm.z() is the slice thickness too (contiguous
  // slices, the partial volume of a scanner's slice profile); withSliceSpacing changes it.
  Eigen::Vector3d spacing_mm{0.8, 0.8, 1.25};
  bool oblique = false;  // tilt the grid 12° about an in-plane diagonal axis
  // The box and the fiducial centres are in LPS (mm), with the grid centred on (0, 0, 0).
  Eigen::Vector3d box_half_extent_mm{30.0, 30.0, 32.0};
  double box_hu = 20.0;  // gelatin
  double air_hu = -1000.0;
  std::vector<Eigen::Vector3d> fiducials_lps_mm{
      {-12.0, -6.0, -18.0}, {14.0, -4.0, 6.0}, {2.0, 16.0, 20.0}};
  double fiducial_radius_mm = 1.5;
  double fiducial_hu = 3000.0;  // metal-like
  // Seeds, seen through the scanner's point spread: a Gaussian of seed_psf_sigma_mm applied
  // before the voxels average (the seeds only: the box and the fiducials keep their supersampled
  // edges). 0.4 mm (FWHM 0.94 mm) is a typical CT's in-plane spread; with none at all, the image
  // of a seed thinner than a voxel is aliased as no scanner's is. Titanium-like on an
  // extended-HU scale by default.
  std::vector<PhantomSeed> seeds;
  // A needle left in (cannula and stylet): cylinders end to end along its centreline
  // (appendWire), drawn as the seeds are, of the same metal.
  std::vector<PhantomSeed> needle_segments;
  double seed_hu = 7000.0;
  double seed_psf_sigma_mm = 0.4;
  // The CT's own noise: white, Gaussian, this SD (HU) in every voxel, added before the values
  // are rounded to whole HU (which adds 1/12 HU² of variance). 0: none.
  double noise_sigma_hu = 0.0;
  std::uint64_t seed = 1;  // noise and UIDs are deterministic functions of the seed
};

// The same field of view cut into slices slice_mm apart and as thick: dims[2] is chosen so the
// grid's extent across the slices stays within half a slice of spec's (the grid stays centred
// on LPS 0, 0, 0); everything else is kept. Errors for a slice_mm that is not finite and
// positive, or that would need more than 4096 slices.
Expected<PhantomSpec> withSliceSpacing(PhantomSpec spec, double slice_mm);

// Appends a wire of diameter_mm along the polyline (LPS) to spec.needle_segments: one cylinder
// per pair of consecutive distinct points.
void appendWire(PhantomSpec& spec, const std::vector<Eigen::Vector3d>& polyline_lps_mm,
                double diameter_mm);

// The phantom's grid: its voxel geometry alone, centred on LPS (0, 0, 0), without rendering it.
Geometry phantomGeometry(const PhantomSpec& spec);

// The phantom as a volume (HU, scale 1). Errors for non-positive sizes, a fiducial that is not
// finite, a noise SD that is negative or not finite, or a seed that is not finite or has a zero
// axis or a non-positive size (named by its number, from 1).
Expected<Volume> makePhantom(const PhantomSpec& spec);

struct DicomWriteOptions {
  std::uint64_t seed = 1;  // UIDs derive from it, so the same phantom gets the same UIDs
  std::string patient_name = "IGNAV^PHANTOM";
  std::string series_description = "ignav phantom";
  // Write InstanceNumber in reverse slice order, to prove readers order by geometry.
  bool reverse_instance_numbers = false;
};

// One CT Image Storage file per slice (slice_0000.dcm ...), PixelRepresentation 0 with
// RescaleIntercept -1024 as scanners write it. Returns the file paths written.
Expected<std::vector<std::string>> writeDicomSeries(const Volume& volume, const std::string& dir,
                                                    const DicomWriteOptions& options = {});

}  // namespace ignav::volume
