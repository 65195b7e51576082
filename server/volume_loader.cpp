#include "volume_loader.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <memory>

#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/load.hpp"
#include "ignav/volume/phantom.hpp"

namespace ignav::server {
namespace {

namespace fs = std::filesystem;
using workflow::Input;
using workflow::InputKind;

Input failed(const std::string& why) {
  Input in;
  in.kind = InputKind::kVolumeLoadFailed;
  in.error = why;
  return in;
}

}  // namespace

VolumeLoader::~VolumeLoader() {
  if (thread_.joinable()) thread_.join();
}

void VolumeLoader::start(const std::string& source, const config::Robot& robot,
                         const fs::path& session_dir) {
  if (thread_.joinable()) thread_.join();
  thread_ = std::thread([this, source, &robot, session_dir] {
    Input in = load(source, robot, session_dir);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_.push_back(std::move(in));
    }
    waitset_.trigger();
  });
}

std::vector<Input> VolumeLoader::finished() {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<Input> out(done_.begin(), done_.end());
  done_.clear();
  return out;
}

Input VolumeLoader::load(const std::string& source, const config::Robot& robot,
                         const fs::path& session_dir) {
  Input in;
  std::string path = source;
  if (source == kPhantomSource && fs::exists(session_dir / "phantom_ct")) {
    path = (session_dir / "phantom_ct").string();  // recovery: the series written before
  } else if (source == kPhantomSource) {
    // The built-in phantom is written as a real DICOM series into the session and read back
    // like any scan.
    auto rp = registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan);
    if (!rp) return failed(rp.error().message);
    rp->spec.oblique = true;
    rp->spec.noise_sigma_hu = 8.0;
    auto v = volume::makePhantom(rp->spec);
    if (!v) return failed(v.error().message);
    path = (session_dir / "phantom_ct").string();
    auto files = volume::writeDicomSeries(*v, path);
    if (!files) return failed(files.error().message);
  }
  volume::DicomLoadOptions options;
  done_files_ = total_files_ = 0;
  options.progress = [this](const volume::Progress& p) {
    total_files_ = p.total;
    done_files_ = p.done;
    // Wake the event loop about every 5 % so the progress reaches clients.
    if (p.total == 0 || p.done % std::max<std::size_t>(1, p.total / 20) == 0) {
      waitset_.trigger();
    }
  };
  auto loaded = volume::loadVolume(path, options);
  if (!loaded) return failed(loaded.error().message);
  in.kind = InputKind::kVolumeLoaded;
  const auto& g = loaded->volume.geometry;
  in.loaded.source = source;
  in.loaded.description = fmt::format(
      "{} x {} x {} voxels, {:.2f} x {:.2f} x {:.2f} mm, {}", g.dims[0], g.dims[1], g.dims[2],
      g.spacing_mm.x(), g.spacing_mm.y(), g.spacing_mm.z(), loaded->volume.description);
  in.loaded.volume = std::make_shared<const volume::Volume>(std::move(loaded->volume));
  return in;
}

}  // namespace ignav::server
