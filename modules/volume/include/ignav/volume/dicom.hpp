// DICOM CT series ingestion with DCMTK: folders or files in, one Volume out, with every series
// found listed and every skipped file or irregularity reported.
#pragma once

#include <string>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::volume {

struct DicomSeriesSummary {
  std::string uid;
  std::string modality;
  std::string description;
  std::size_t files = 0;
  std::size_t frames = 0;  // slices: files, or the frames of multi-frame files
};

struct DicomLoadOptions {
  std::string series_uid;  // "" = the largest CT series (or the largest image series)
  // Missing slices (a gap of whole slice spacings) are an error unless this is set; then the
  // missing slices are filled by linear interpolation and each fill is listed in warnings.
  bool fill_missing_slices = false;
  ProgressCallback progress;
  // Files decoded in parallel (0: one per hardware thread, at most 8). The volume is the same
  // whatever the count; progress is reported from the calling thread only.
  int threads = 0;
};

struct DicomLoadResult {
  Volume volume;
  std::vector<DicomSeriesSummary> series;  // every image series found, largest first
  std::vector<std::string> notes;          // skipped files and why (DICOMDIR, SR, not DICOM)
  std::vector<std::string> warnings;       // irregularities accepted (filled gaps, ...)
};

// `paths`: files and/or folders (searched recursively). Slices are ordered along the slice
// normal by ImagePositionPatient, never by file name or InstanceNumber.
Expected<DicomLoadResult> readDicomSeries(const std::vector<std::string>& paths,
                                          const DicomLoadOptions& options = {});

}  // namespace ignav::volume
