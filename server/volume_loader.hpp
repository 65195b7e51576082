// Volume loads (DICOM series, NRRD, the built-in phantom) on a thread of their own, the loader
// thread: one load at a time; its result comes back to the event thread as an input
// (volume_loaded or volume_load_failed) through finished(), with the waitset woken.
#pragma once

#include <atomic>
#include <cstddef>
#include <deque>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "ignav/config/robot_config.hpp"
#include "ignav/protocol/wire/dds.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::server {

// The source that names the built-in phantom (written as a DICOM series into the session).
constexpr const char* kPhantomSource = "phantom:";

class VolumeLoader {
 public:
  explicit VolumeLoader(protocol::WaitSet& waitset) : waitset_(waitset) {}
  ~VolumeLoader();  // waits for a load under way
  VolumeLoader(const VolumeLoader&) = delete;
  VolumeLoader& operator=(const VolumeLoader&) = delete;

  // Starts loading `source` on the loader thread (after the previous load, if any, ended).
  void start(const std::string& source, const config::Robot& robot,
             const std::filesystem::path& session_dir);

  // Files read so far and in all (0 when unknown), updated from the loader thread.
  std::pair<std::size_t, std::size_t> progress() const { return {done_files_, total_files_}; }

  // The loads that ended since last time, as inputs.
  std::vector<workflow::Input> finished();

  // The load itself: run on the loader thread by start(), or directly for crash recovery.
  workflow::Input load(const std::string& source, const config::Robot& robot,
                       const std::filesystem::path& session_dir);

 private:
  protocol::WaitSet& waitset_;
  std::atomic<std::size_t> done_files_{0}, total_files_{0};
  std::thread thread_;
  std::mutex mutex_;
  std::deque<workflow::Input> done_;
};

}  // namespace ignav::server
