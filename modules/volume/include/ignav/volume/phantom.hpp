// The built-in phantom: a gelatin-like box in air with bright spherical fiducials, rendered with
// partial-volume edges, and a DICOM CT series writer (DCMTK) so the phantom is a real series
// that any DICOM reader opens.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::volume {

struct PhantomSpec {
  std::array<int, 3> dims{96, 96, 64};
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
  double noise_sigma_hu = 0.0;
  std::uint64_t seed = 1;  // noise and UIDs are deterministic functions of the seed
};

// The phantom's grid: its voxel geometry alone, centred on LPS (0, 0, 0), without rendering it.
Geometry phantomGeometry(const PhantomSpec& spec);

// The phantom as a volume (HU, scale 1). Errors for non-positive sizes or a fiducial that is
// not finite.
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
