// load_volume's background job (background_jobs.hpp): read the CT, or make the built-in phantom
// as a real DICOM series in the session folder and read that back like any scan.
#include <fmt/format.h>

#include <algorithm>
#include <memory>

#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/load.hpp"
#include "ignav/volume/phantom.hpp"
#include "ignav/workflow/background_jobs.hpp"

namespace ignav::workflow {

Input loadCt(std::uint64_t job, const std::string& source, const config::Robot& robot,
             const JobContext& context) {
  namespace fs = std::filesystem;
  Input in;
  in.job = job;
  in.path = source;
  in.kind = InputKind::kVolumeLoadFailed;
  auto failed = [&](const std::string& why) {
    in.error = why;
    return in;
  };
  std::string path = source;
  const fs::path phantom_dir = context.session_dir / "phantom_ct";
  std::error_code ec;
  if (source == kPhantomSource && fs::exists(phantom_dir, ec)) {
    path = phantom_dir.string();  // replay or recovery: the series written before
  } else if (source == kPhantomSource) {
    auto rp = registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan);
    if (!rp) return failed(rp.error().message);
    rp->spec.oblique = true;
    rp->spec.noise_sigma_hu = 8.0;
    auto v = volume::makePhantom(rp->spec);
    if (!v) return failed(v.error().message);
    path = phantom_dir.string();
    auto files = volume::writeDicomSeries(*v, path);
    if (!files) return failed(files.error().message);
  }
  volume::DicomLoadOptions options;
  if (context.progress) {
    options.progress = [&](const volume::Progress& p) { context.progress(p.done, p.total); };
  }
  auto loaded = volume::loadVolume(path, options);
  if (!loaded) return failed(loaded.error().message);
  in.kind = InputKind::kVolumeLoaded;
  const auto& g = loaded->volume.geometry;
  in.loaded.source = source;
  in.loaded.description = fmt::format(
      "{} x {} x {} voxels, {:.2f} x {:.2f} x {:.2f} mm, {}", g.dims[0], g.dims[1], g.dims[2],
      g.spacing_mm.x(), g.spacing_mm.y(), g.spacing_mm.z(), loaded->volume.description);
  in.summary = in.loaded.description;
  in.loaded.volume = std::make_shared<const volume::Volume>(std::move(loaded->volume));
  return in;
}

}  // namespace ignav::workflow
