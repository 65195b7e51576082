// auto_fiducials' marker detection as a job: what the reducer asks the server to run, and the run
// itself, whose outcome comes back to the reducer as an input (issue 22). Pure: the server runs
// it on a thread of its own; replaying a format-1 journal runs it inside the step.
#include "ignav/registration/fiducial_detection.hpp"
#include "ignav/workflow/reducer.hpp"

namespace ignav::workflow {

std::optional<FiducialDetectionJob> pendingDetection(const Session& s) {
  if (s.detecting == 0 || !s.ct.volume || !s.robot) return std::nullopt;
  FiducialDetectionJob job;
  job.job = s.detecting;
  job.volume = s.ct.volume;
  job.ct_source = s.ct.source;
  job.search = s.robot->config.registration.fiducials;
  job.model_mm.assign(s.robot->feature_points_mm.begin(), s.robot->feature_points_mm.end());
  return job;
}

Input detectFiducials(const FiducialDetectionJob& job) {
  Input in;
  in.job = job.job;
  in.path = job.ct_source;
  in.kind = InputKind::kFiducialDetectionFailed;
  if (!job.volume) {
    in.error = "no CT to search";
    return in;
  }
  auto found = registration::findFiducials(*job.volume, job.search, job.model_mm);
  if (!found) {
    in.error = found.error().message;
    return in;
  }
  if (!found->match) {
    in.error = found->summary;
    return in;
  }
  in.kind = InputKind::kFiducialsDetected;
  for (std::size_t k : found->match->candidate)
    in.points.push_back(found->candidates[k].centroid_lps_mm);
  in.summary = found->summary;
  return in;
}

}  // namespace ignav::workflow
