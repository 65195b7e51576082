// Background work the workflow asks for, each kind declared once (issue 39): what runs, on what
// snapshot, which inputs its outcome becomes, how a stale outcome is recognised. The server's job
// thread (server/job_runner.hpp), the reducer's staleness check, crash recovery and
// docs/WORKFLOW.md's table of jobs all come from kJobKinds (src/background_jobs.cpp).
//
// The life of a job: an action marks the session as awaiting it (a field holding the revision of
// the step that asked) and names its kind in Effects::start_jobs; after the step the server makes
// the job from the new session (pending) and hands it to the job thread; its outcome comes back
// as an input naming the job. An outcome the session no longer awaits (a new CT, a registration
// given by hand meanwhile) is refused as stale and changes nothing. Outcomes are journaled like
// any input, so replay never runs a job; after a crash, the jobs the recovered session awaits are
// started again (pendingJobs).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ignav/workflow/session.hpp"

namespace ignav::workflow {

// In the order the job thread prefers them when several are queued (a CT before what is found on
// it).
enum class JobKind {
  kVolumeLoad,
  kMarkerDetection,
  kConfirmationMeasurement,
  kNeedleScan,
  kStructureLoad,
  kTargetProposal,
  kRobotPlacement,
  kPlacementCheck,
  kDoseComputation
};

// What the job thread gives every run besides its snapshot: the session folder (for files a job
// leaves for people, such as the built-in phantom's DICOM series) and where to say how far it is.
struct JobContext {
  std::filesystem::path session_dir;
  // Units done of all (total 0: unknown); clients see it (VolumeState's files read). May be empty.
  std::function<void(std::size_t done, std::size_t total)> progress;
};

// One job, ready to run off the event thread: `run` holds an immutable snapshot of what it needs
// (shared_ptr<const ...>, copies) and touches no session.
struct BackgroundJob {
  JobKind kind = JobKind::kMarkerDetection;
  std::uint64_t id = 0;  // the revision of the step that asked for it: its outcome names it
  std::string source;    // what it runs on, for the log and a failure's input
  std::function<Input(const JobContext&)> run;
};

struct JobKindSpec {
  JobKind kind;
  const char* name;     // "marker detection"
  InputKind succeeded;  // the outcome inputs; `failed` also when the run throws
  InputKind failed;
  // The job of this kind the session awaits (0: none); an outcome naming another is stale.
  std::uint64_t (*awaited)(const Session& session);
  // The awaited job, from the session (none when none is awaited): started after the step that
  // asked for it, and again after a crash.
  std::optional<BackgroundJob> (*pending)(const Session& session);
  // Why an outcome is not the awaited one, for its rejection.
  std::string (*stale)(const Session& session, const Input& outcome);
};

const std::vector<JobKindSpec>& jobKinds();  // in JobKind order
const JobKindSpec& jobKindSpec(JobKind kind);
// The kind whose outcome `kind` is; nullptr for any other input.
const JobKindSpec* jobOfOutcome(InputKind kind);
// Every job the session awaits (what a recovered server starts again), in JobKind order.
std::vector<BackgroundJob> pendingJobs(const Session& session);
// The outcome of a run that could not finish (it threw): its kind's failure, naming the job.
Input failedOutcome(const BackgroundJob& job, const std::string& why);

// ---- The runs of the kinds declared since issue 39 (each in a file of its own) ----

// The source that names the built-in phantom (written as a DICOM series into the session folder,
// then read back like any scan).
constexpr const char* kPhantomSource = "phantom:";

// load_volume's job (ct_load.cpp): the CT at `source` (a DICOM folder or file, .nrrd/.nhdr,
// .mha/.mhd, or kPhantomSource, made for `robot`) as volume_loaded naming `job`, or
// volume_load_failed with why. Replay and crash recovery call it to read a journaled CT again.
Input loadCt(std::uint64_t job, const std::string& source, const config::Robot& robot,
             const JobContext& context);

// How far around a structure its distance field reaches: a needle farther away is at least this
// far (more than any margin, at most 10 mm, and its uncertainty need).
constexpr double kStructureReach_mm = 15.0;

// load_structures' job (structure_load.cpp): the segmentation at `source`, checked to lie on
// `ct`'s grid, with the site's roles and a distance field per structure, as structures_loaded
// naming `job` (its summary names each structure with its role and voxels), or
// structures_load_failed with why. kPhantomSource: the built-in phantom's anatomy, drawn on its
// CT for `robot` (and written to the session folder for people and other tools, as
// phantom_anatomy.seg.nrrd and as the RT Structure Set phantom_anatomy_rtstruct.dcm). DICOM
// structures are drawn on the CT and checked against its frame of reference.
// Replay and crash recovery call it to read them again.
Input loadStructures(std::uint64_t job, const std::string& source, const LoadedCt& ct,
                     const std::optional<anatomy::Site>& site, const config::Robot& robot,
                     const JobContext& context);
// The finest lattice propose_targets tries, and the most points it tries (each is a target's
// whole evaluation: inverse kinematics, aim, clearance).
constexpr double kMinProposalSpacing_mm = 1.0;
constexpr double kMaxProposalSpacing_mm = 30.0;
constexpr std::size_t kMaxProposalCandidates = 20000;

// propose_targets' job (target_proposal.cpp): on `snapshot` (the session when it was asked), the
// points of a lattice of `spacing_mm` in the robot's frame (through the structure's centroid)
// that lie inside `structure`, evaluated as targets would be; those reachable with every
// clearance kept, at most as many as the plan can still take, in the order the plan would visit
// them, as targets_proposed naming `job` (`points`; `summary` says what was left out and why), or
// target_proposal_failed with why (none, or more than the plan can take: a spacing that gives
// fewer).
Input proposeTargets(std::uint64_t job, const std::string& structure, double spacing_mm,
                     const std::shared_ptr<const Session>& snapshot, const JobContext& context);

// plan_seeds' job (seed_planning.cpp): the candidates propose_targets would keep on a lattice of
// `spacing_mm` in `structure` (each a seed's place, its axis the needle's at the tip), then the
// fewest seeds of the asked model and strength among them whose dose covers the structure
// (V100 ≥ 95 %, D90 ≥ 100 %) with every avoided structure within the site's dose limits
// (dosimetry::planSeeds), beside uniform loading's count; as targets_proposed naming `job`
// (`points` in the order the plan would visit them; `summary` the metrics), or
// target_proposal_failed with why (no candidates, no plan meets the limits, more seeds than the
// plan can take, an unreadable seed model).
Input planSeedTargets(std::uint64_t job, const std::string& structure, double spacing_mm,
                      const SeedPlanAsk& ask, const std::shared_ptr<const Session>& snapshot,
                      const JobContext& context);

// What robot placement (robot_placement.cpp) works on, taken from the session when it was asked:
// the robot, the CT (for the skin), the structures with their roles and fields, the tissue (its
// predicted drift widens every margin, as in the session's clearance).
struct PlacementScene {
  std::shared_ptr<const config::Robot> robot;
  std::shared_ptr<const volume::Volume> ct;
  LoadedStructures structures;
  std::vector<StructureRoleChoice> roles;
  std::optional<config::TissueProfile> tissue;
};
PlacementScene placementScene(const Session& session);

// place_robot's job (robot_placement.cpp): the poses within `limits` from which one insertion
// covers the most of `structure` with every clearance kept (the best and up to three distinct
// alternatives), as robot_placed naming `job` (`placements`, `summary`), or
// robot_placement_failed with why.
Input placeRobot(std::uint64_t job, const std::string& structure,
                 const anatomy::PlacementLimits& limits, const PlacementScene& scene,
                 const JobContext& context);
// After a registration, with a placement proposed: how far the robot stands from the best pose
// (`proposed`) and what it covers of `structure` from there, as placement_checked naming `job`
// (`mounted`, `summary`), or placement_check_failed with why.
Input checkPlacement(std::uint64_t job, const std::string& structure,
                     const placement::PlacedPose& proposed, const anatomy::PlacementLimits& limits,
                     const registration::Registration& registration, const PlacementScene& scene,
                     const JobContext& context);

// The built-in phantom's anatomy in the robot's frame (phantom_anatomy.cpp): a prostate filling
// the feasible volume (target), a urethra through it (avoid 3 mm), a rectum behind (5 mm), a
// pubic arch in front (2 mm).
std::vector<anatomy::Shape> phantomAnatomy(const kinematics::Kinematics& kinematics);

// How far around the dosed structure's box the dose grid reaches (the CT's voxels): the organs
// near it, and the 50 % isodose of a prostate implant.
constexpr double kDoseMargin_mm = 20.0;

// compute_dose's job (dose_computation.cpp), for the session's DoseStatus (its seeds' model, its
// structure, the seeds as they were asked): the dose of the plannable targets as seeds
// ("planned") and of the confirmation CT's seeds ("delivered"), on the CT's voxels within
// kDoseMargin_mm of the structure, each judged on every voxel of the structures, as dose_computed
// naming `job` (`summary` gives the metrics; `error` what could not be written), or dose_failed
// with why. With a session folder, into its dose/: the RT Structure Set, an RT Plan per set of
// seeds, each dose as RT Dose and NRRD, the DVHs as dvh.png and dvh.csv.
Input computeDose(std::uint64_t job, const std::shared_ptr<const Session>& snapshot,
                  const JobContext& context);

}  // namespace ignav::workflow
