// load_confirmation's measuring job (issue 23): the scan loaded, the robot's markers found (as
// auto_fiducials finds them) and the seeds found clear of them. Pure but slow (I/O, a threshold
// scan of the whole volume): the server runs it on its job thread; the reducer gets the
// outcome as confirmation_measured (markers, seeds and any needle's tip) or confirmation_failed
// (why).
#include <fmt/format.h>
#include <Eigen/Geometry>
#include <Eigen/LU>

#include "ignav/verification/needle_detection.hpp"
#include "ignav/verification/seed_detection.hpp"
#include "ignav/volume/load.hpp"
#include "ignav/workflow/reducer.hpp"
#include "session_rules.hpp"

namespace ignav::workflow {

std::optional<ConfirmationJob> pendingConfirmation(const Session& s) {
  if (s.confirmation.measuring == 0 || !s.robot) return std::nullopt;
  return ConfirmationJob{s.confirmation.measuring, s.confirmation.measuring_source, s.robot,
                         s.confirmation.measuring_matrix};
}

Input measureConfirmation(const ConfirmationJob& job) {
  Input in;
  in.kind = InputKind::kConfirmationFailed;
  in.job = job.job;
  in.path = job.source;
  if (!job.robot) {
    in.error = "no robot to search the markers of";
    return in;
  }
  auto loaded = volume::loadVolume(job.source, {});
  if (!loaded) {
    in.error = "cannot load " + job.source + ": " + loaded.error().message;
    return in;
  }
  FiducialDetectionJob markers;
  markers.volume = std::make_shared<const volume::Volume>(std::move(loaded->volume));
  markers.ct_source = job.source;
  markers.search = job.robot->config.registration.fiducials;
  markers.model_mm.assign(job.robot->feature_points_mm.begin(), job.robot->feature_points_mm.end());
  Input found;
  if (job.image_to_robot) {
    // Registered by the given transform: the markers lie where it puts the feature points (the
    // seed search keeps clear of them there), found or merged with a needle left in.
    const Eigen::Matrix4d robot_to_image = job.image_to_robot->inverse();
    for (const auto& p : markers.model_mm)
      found.points.push_back((robot_to_image * p.homogeneous()).head<3>());
  } else {
    found = detectFiducials(markers);
    if (found.kind != InputKind::kFiducialsDetected) {
      in.error = fmt::format(
          "markers_missing: the robot's markers were not found on {} ({}): the scan cannot be "
          "registered to the robot (another patient or frame, or not a scan of the robot? A "
          "needle left in touches the markers on its axis: give the registration with the scan)",
          job.source, found.error);
      return in;
    }
  }
  verification::SeedSearch search;
  search.markers_lps_mm = found.points;
  auto seeds = verification::findSeeds(*markers.volume, search);
  if (!seeds) {
    in.error = "the seed search on " + job.source + " failed: " + seeds.error().message;
    return in;
  }
  // A needle still in: the way it goes in is the robot's −Z, through the markers' own fit (the
  // reducer registers the scan properly, reused or anew; a direction needs no more). Markers that
  // do not register leave the needle search out; the reducer refuses the scan for them.
  Expected<verification::NeedleDetection> needles{verification::NeedleDetection{}};
  std::optional<Eigen::Matrix4d> image_to_robot = job.image_to_robot;
  if (!image_to_robot) {
    if (auto reg = detail::registerOnRobot(*job.robot, found.points)) {
      image_to_robot = reg->imageToRobot();
    }
  }
  if (image_to_robot) {
    verification::NeedleSearch needle_search;
    needle_search.markers_lps_mm = found.points;
    needle_search.insertion_lps =
        image_to_robot->topLeftCorner<3, 3>().inverse() * Eigen::Vector3d(0.0, 0.0, -1.0);
    needles = verification::findNeedles(*markers.volume, needle_search);
  }
  if (!needles) {
    in.error = "the needle search on " + job.source + " failed: " + needles.error().message;
    return in;
  }
  in.kind = InputKind::kConfirmationMeasured;
  in.loaded.volume = markers.volume;
  in.points = found.points;
  in.summary = seeds->summary;
  if (!needles->needles.empty()) in.summary += "; " + needles->summary;
  std::uint32_t id = 0;
  for (const auto& c : seeds->seeds) {
    FoundSeed s;
    s.id = ++id;
    s.lps_mm = c.centroid_lps_mm;
    s.length_mm = c.length_mm;
    s.width_mm = c.width_mm;
    in.seeds.push_back(s);
  }
  for (const auto& n : needles->needles) {
    FoundSeed s;
    s.id = ++id;
    s.kind = "tip";
    s.lps_mm = n.tip_lps_mm;
    s.width_mm = n.tip_diameter_mm;
    s.path_lps_mm = n.centreline_lps_mm;
    in.seeds.push_back(s);
  }
  return in;
}

}  // namespace ignav::workflow
