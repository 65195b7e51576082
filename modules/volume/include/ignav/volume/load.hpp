// One entry point for every volume source a user names: a DICOM folder or file, NRRD or
// MetaImage.
#pragma once

#include <string>
#include <vector>

#include "ignav/volume/dicom.hpp"

namespace ignav::volume {

struct LoadedVolume {
  Volume volume;
  std::vector<DicomSeriesSummary> series;  // DICOM only
  std::vector<std::string> notes;          // skipped files
  std::vector<std::string> warnings;       // irregularities accepted
};

// A folder or a .dcm/.dicom/extension-less file goes to the DICOM reader (options apply);
// .nrrd/.nhdr/.mha/.mhd to the NRRD/MetaImage readers.
Expected<LoadedVolume> loadVolume(const std::string& path, const DicomLoadOptions& options = {});

}  // namespace ignav::volume
