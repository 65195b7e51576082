#include "ignav/volume/load.hpp"

#include <algorithm>
#include <filesystem>

#include "ignav/volume/image_io.hpp"

namespace ignav::volume {

Expected<LoadedVolume> loadVolume(const std::string& path, const DicomLoadOptions& options) {
  namespace fs = std::filesystem;
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  LoadedVolume out;
  if (ext == ".nrrd" || ext == ".nhdr" || ext == ".mha" || ext == ".mhd") {
    auto v = readVolumeFile(path, options.progress);
    if (!v) return v.error();
    out.volume = std::move(v).value();
    return out;
  }
  auto d = readDicomSeries({path}, options);
  if (!d) return d.error();
  out.volume = std::move(d->volume);
  out.series = std::move(d->series);
  out.notes = std::move(d->notes);
  out.warnings = std::move(d->warnings);
  return out;
}

}  // namespace ignav::volume
