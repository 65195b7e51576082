// The kinds of background work (background_jobs.hpp). Adding one: its JobKind, its row here, its
// run (a pure function of a snapshot, in a file of its own), the session field that says it is
// awaited, and its outcome inputs with their transitions (docs/ARCHITECTURE.md, "Adding a
// background job").
#include "ignav/workflow/background_jobs.hpp"

#include <fmt/format.h>

#include <stdexcept>

#include "ignav/core/table_order.hpp"
#include "ignav/workflow/reducer.hpp"
#include "session_rules.hpp"

namespace ignav::workflow {
namespace {

std::optional<BackgroundJob> ctLoad(const Session& s) {
  if (s.volume_status.status != "loading" || !s.robot) return std::nullopt;
  return BackgroundJob{
      JobKind::kVolumeLoad, s.ct_revision, s.volume_status.source,
      [job = s.ct_revision, source = s.volume_status.source, robot = s.robot](
          const JobContext& context) { return loadCt(job, source, *robot, context); }};
}

std::string staleLoad(const Session& s, const Input& in) {
  return fmt::format("CT load #{} ({}) is not the one awaited ({}): ignored", in.job,
                     in.kind == InputKind::kVolumeLoaded ? in.loaded.source : in.path,
                     s.volume_status.status == "loading"
                         ? fmt::format("#{}, {}", s.ct_revision, s.volume_status.source)
                         : "none is loading");
}

std::optional<BackgroundJob> markerDetection(const Session& s) {
  auto job = pendingDetection(s);
  if (!job) return std::nullopt;
  return BackgroundJob{JobKind::kMarkerDetection, job->job, job->ct_source,
                       [job = std::move(*job)](const JobContext&) { return detectFiducials(job); }};
}

std::optional<BackgroundJob> confirmationMeasurement(const Session& s) {
  auto job = pendingConfirmation(s);
  if (!job) return std::nullopt;
  return BackgroundJob{
      JobKind::kConfirmationMeasurement, job->job, job->source,
      [job = std::move(*job)](const JobContext&) { return measureConfirmation(job); }};
}

std::optional<BackgroundJob> needleScan(const Session& s) {
  auto job = pendingNeedleScan(s);
  if (!job) return std::nullopt;
  return BackgroundJob{JobKind::kNeedleScan, job->scan.job, job->scan.source,
                       [job = std::move(*job)](const JobContext&) { return scanNeedle(job); }};
}

std::string staleNeedleScan(const Session& s, const Input& in) {
  return fmt::format("intermittent CT search #{} ({}) is not the one awaited (#{}): ignored",
                     in.job, in.path, s.scanning_needle);
}

std::optional<BackgroundJob> structureLoad(const Session& s) {
  if (s.structures.loading == 0) return std::nullopt;
  return BackgroundJob{JobKind::kStructureLoad, s.structures.loading, s.structures.source,
                       [job = s.structures.loading, source = s.structures.source, ct = s.ct,
                        site = s.site, robot = s.robot](const JobContext& context) {
                         return loadStructures(job, source, ct, site, *robot, context);
                       }};
}

std::optional<BackgroundJob> targetProposal(const Session& s) {
  const auto& p = s.proposals;
  if (p.proposing == 0) return std::nullopt;
  // The session as it was asked: every candidate is judged by the same rules a target is.
  return BackgroundJob{
      JobKind::kTargetProposal, p.proposing, fmt::format("{} {:g} mm", p.structure, p.spacing_mm),
      [job = p.proposing, structure = p.structure, spacing = p.spacing_mm, seed_plan = p.seed_plan,
       snapshot = std::make_shared<const Session>(s)](const JobContext& context) {
        if (seed_plan)
          return planSeedTargets(job, structure, spacing, *seed_plan, snapshot, context);
        return proposeTargets(job, structure, spacing, snapshot, context);
      }};
}

std::optional<BackgroundJob> robotPlacement(const Session& s) {
  const auto& p = s.robot_placement;
  if (p.placing == 0) return std::nullopt;
  return BackgroundJob{JobKind::kRobotPlacement, p.placing,
                       fmt::format("{} from {}", p.structure, p.limits.approach),
                       [job = p.placing, structure = p.structure, limits = p.limits,
                        scene = placementScene(s)](const JobContext& context) {
                         return placeRobot(job, structure, limits, scene, context);
                       }};
}

std::optional<BackgroundJob> doseComputation(const Session& s) {
  const auto& d = s.dose;
  if (d.computing == 0) return std::nullopt;
  return BackgroundJob{
      JobKind::kDoseComputation, d.computing,
      fmt::format("{} for '{}'", d.seeds ? d.seeds->seed_model : "", d.structure),
      [job = d.computing, snapshot = std::make_shared<const Session>(s)](
          const JobContext& context) { return computeDose(job, snapshot, context); }};
}

std::optional<BackgroundJob> placementCheck(const Session& s) {
  const auto& p = s.robot_placement;
  if (p.checking == 0 || p.poses.empty() || !s.registration) return std::nullopt;
  return BackgroundJob{
      JobKind::kPlacementCheck, p.checking, p.structure,
      [job = p.checking, structure = p.structure, proposed = p.poses.front(), limits = p.limits,
       registration = *s.registration, scene = placementScene(s)](const JobContext& context) {
        return checkPlacement(job, structure, proposed, limits, registration, scene, context);
      }};
}

// "robot placement #12 (prostate) is not the one awaited (#15): ignored"
std::string staleJob(const char* what, std::uint64_t awaited, const Input& in) {
  return fmt::format("{} #{} ({}) is not the one awaited ({}): ignored", what, in.job, in.path,
                     awaited ? fmt::format("#{}", awaited) : "none is");
}

std::string staleMeasurement(const Session& s, const Input& in) {
  return fmt::format("confirmation CT measurement #{} ({}) is not the one awaited (#{}): ignored",
                     in.job, in.path, s.confirmation.measuring);
}

const std::vector<JobKindSpec> kJobKinds = {
    // kind, name, outcome inputs (succeeded, failed), awaited, pending, stale
    {JobKind::kVolumeLoad, "CT load", InputKind::kVolumeLoaded, InputKind::kVolumeLoadFailed,
     [](const Session& s) { return s.volume_status.status == "loading" ? s.ct_revision : 0; },
     ctLoad, staleLoad},
    {JobKind::kMarkerDetection, "marker detection", InputKind::kFiducialsDetected,
     InputKind::kFiducialDetectionFailed, [](const Session& s) { return s.detecting; },
     markerDetection, detail::staleDetection},
    {JobKind::kConfirmationMeasurement, "confirmation CT measurement",
     InputKind::kConfirmationMeasured, InputKind::kConfirmationFailed,
     [](const Session& s) { return s.confirmation.measuring; }, confirmationMeasurement,
     staleMeasurement},
    {JobKind::kNeedleScan, "intermittent CT search", InputKind::kNeedleScanned,
     InputKind::kNeedleScanFailed, [](const Session& s) { return s.scanning_needle; }, needleScan,
     staleNeedleScan},
    {JobKind::kStructureLoad, "structure load", InputKind::kStructuresLoaded,
     InputKind::kStructuresLoadFailed, [](const Session& s) { return s.structures.loading; },
     structureLoad,
     [](const Session& s, const Input& in) {
       return staleJob("structure load", s.structures.loading, in);
     }},
    {JobKind::kTargetProposal, "target proposal", InputKind::kTargetsProposed,
     InputKind::kTargetProposalFailed, [](const Session& s) { return s.proposals.proposing; },
     targetProposal,
     [](const Session& s, const Input& in) {
       return staleJob("target proposal", s.proposals.proposing, in);
     }},
    {JobKind::kRobotPlacement, "robot placement", InputKind::kRobotPlaced,
     InputKind::kRobotPlacementFailed, [](const Session& s) { return s.robot_placement.placing; },
     robotPlacement,
     [](const Session& s, const Input& in) {
       return staleJob("robot placement", s.robot_placement.placing, in);
     }},
    {JobKind::kPlacementCheck, "placement check", InputKind::kPlacementChecked,
     InputKind::kPlacementCheckFailed, [](const Session& s) { return s.robot_placement.checking; },
     placementCheck,
     [](const Session& s, const Input& in) {
       return staleJob("placement check", s.robot_placement.checking, in);
     }},
    {JobKind::kDoseComputation, "dose computation", InputKind::kDoseComputed,
     InputKind::kDoseFailed, [](const Session& s) { return s.dose.computing; }, doseComputation,
     [](const Session& s, const Input& in) {
       return staleJob("dose computation", s.dose.computing, in);
     }},
};

}  // namespace

const std::vector<JobKindSpec>& jobKinds() {
  static const bool ok = inEnumOrder(kJobKinds, &JobKindSpec::kind);
  if (!ok) throw std::logic_error("background job table is not in JobKind order");
  return kJobKinds;
}

const JobKindSpec& jobKindSpec(JobKind kind) {
  return jobKinds().at(static_cast<std::size_t>(kind));
}

const JobKindSpec* jobOfOutcome(InputKind kind) {
  for (const auto& spec : jobKinds())
    if (spec.succeeded == kind || spec.failed == kind) return &spec;
  return nullptr;
}

std::vector<BackgroundJob> pendingJobs(const Session& session) {
  std::vector<BackgroundJob> out;
  for (const auto& spec : jobKinds())
    if (auto job = spec.pending(session)) out.push_back(std::move(*job));
  return out;
}

Input failedOutcome(const BackgroundJob& job, const std::string& why) {
  Input in;
  in.kind = jobKindSpec(job.kind).failed;
  in.job = job.id;
  in.path = job.source;
  in.error = why;
  return in;
}

}  // namespace ignav::workflow
