// The closed loop's session values (issue 23): a confirmation CT measured against the plan (its
// seeds, its registration, a person's corrections, the targeting errors), the tissue fitted from
// those errors, and the profile the plan aims with. Values only; the actions are in
// src/verification_actions.cpp, the measuring job in src/confirmation.cpp.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/compensation/compensation.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/config/tissue_profiles.hpp"
#include "ignav/registration/point_registration.hpp"
#include "ignav/verification/confirmation_registration.hpp"
#include "ignav/verification/targeting_error.hpp"

namespace ignav::workflow {

// A seed on the confirmation CT (LPS), as the detection found it or a person placed it; or the
// stylet's tip, when the scan still shows the needle (it marks where the needle landed as a seed
// would, and its centreline is what the tissue fit can use besides).
struct FoundSeed {
  std::uint32_t id = 0;       // 1, 2, ... in detection order (seeds, then tips); placed ones follow
  std::string kind = "seed";  // "seed" | "tip"
  Eigen::Vector3d lps_mm = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> path_lps_mm;  // a tip's needle centreline, ending at the tip
  double length_mm = 0.0;                    // 0 for a placed one
  double width_mm = 0.0;
  bool placed = false;    // by place_seed (a person's click)
  bool rejected = false;  // by reject_seed: no seed of this plan
};

// What the server loads and searches off the event thread (load_confirmation); measure() runs it.
struct ConfirmationJob {
  std::uint64_t job = 0;  // the revision of the load_confirmation that asked for it
  std::string source;     // DICOM folder or file, .nrrd/.nhdr, .mha/.mhd
  std::shared_ptr<const config::Robot> robot;
  // Given with load_confirmation: the scan's image -> robot transform; the markers are not
  // searched for (they are expected where it puts the robot's feature points).
  std::optional<Eigen::Matrix4d> image_to_robot;
};

// A person's word on one target's seed (the click fallback).
struct SeedReview {
  std::uint32_t seed_id = 0;  // 0: the target has no seed (never: reject_seed names seeds)
  std::string how;            // "placed" | "accepted"
};

// One measured target: the error, and which seed and how it was matched.
struct MeasuredTarget {
  verification::TargetError error;
  std::uint32_t seed_id = 0;
  std::string matched;  // "detected" | "tip" (the stylet's tip detected) | "accepted" | "placed"
  // The joints it was reached with (Target::reached_joints): what a tissue fit explains, kept
  // here so that a fit still works once the plan's targets are cleared for the next pass.
  kinematics::Joints joints;
  // Where the model (the session's tissue, joints as commanded) predicted the tip would land,
  // robot frame; NaN without a tissue. Its distance from the plan: what the model had predicted.
  Eigen::Vector3d predicted_robot_mm =
      Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double predicted_error_mm = std::numeric_limits<double>::quiet_NaN();
};

// The session's confirmation CT and what it shows.
struct Confirmation {
  // none | measuring (loading and searching the scan) | measured | unmatched (seeds found, but
  // the match needs a person: ambiguous or more seeds than targets; `message` says why)
  std::string status = "none";
  std::string source;
  std::string message;          // for a person: the outcome, or why the last scan was refused
  std::uint64_t measuring = 0;  // the job under way (0: none)
  std::string measuring_source;
  std::optional<Eigen::Matrix4d> measuring_matrix;  // the job's given registration, if any
  std::vector<Eigen::Vector3d> markers_lps_mm;      // on the confirmation CT, in the model's order
  // The scan itself, as measured (for those who show it: OpenIGTLink's GET_IMAGE); none after a
  // replay, which has its measurement but not its voxels.
  std::shared_ptr<const volume::Volume> ct;
  std::optional<verification::ConfirmationRegistration> registration;
  std::string detection_summary;
  std::vector<FoundSeed> seeds;
  std::map<std::uint32_t, SeedReview> reviews;  // by target id
  std::vector<MeasuredTarget> targets;          // matched reached targets, in plan order
  std::vector<std::uint32_t> missing_targets;   // reached, without a seed
  std::vector<std::uint32_t> extra_seeds;       // seed ids matched to no target
  std::optional<verification::ErrorSummary> summary;
  std::string text;  // mean ± SD, max, min, RMS
  // The scan the rows above (targets to text) were measured on: `source`, or while this scan's
  // match needs a person (unmatched), the last one that matched, whose rows stay meanwhile.
  std::string rows_source;
  // The rows are this scan's own (their seed ids name its seeds).
  bool rowsAreThisScans() const { return rows_source == source; }
};

// A tissue fitted from this session's measured errors (fit_tissue): the profile, usable by
// use_tissue now and, as its tissues.yaml entry, by the next session.
struct FittedTissue {
  config::TissueProfile profile;
  compensation::TargetingFit fit;
  std::size_t targets = 0;
  std::string yaml;  // the configs/tissues.yaml entry
};

// The measuring job itself: loads the scan, finds the robot's markers and the seeds. Returns the
// input that brings the outcome back to the reducer (confirmation_measured, or
// confirmation_failed with the reason).
struct Input;
Input measureConfirmation(const ConfirmationJob& job);

// ---- Re-planning during an insertion (issue 40; the job: src/needle_scan.cpp) ----

// One target aimed again from what an intermittent CT showed.
struct ReaimedAim {
  std::uint32_t target_id = 0;
  std::string how;  // "path": this insertion, from its needle's path; "refit": a later one
  kinematics::Joints before;  // what it was aimed with (compensated, or nominal)
  kinematics::Joints joints;  // re-aimed
  // Predicted landings (robot frame) in the model the re-aim used (for "path", carried by the
  // motion the path showed): of the joints before, and of the re-aimed ones.
  Eigen::Vector3d before_landing_robot_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d landing_robot_mm = Eigen::Vector3d::Zero();
};

// What scan_needle found and proposes (needle_scanned); reaim adopts it.
struct ReaimProposal {
  std::uint64_t job = 0;                                 // the scan_needle that asked
  std::string source;                                    // the intermittent CT
  std::uint32_t target_id = 0;                           // the insertion stopped part-way
  kinematics::Joints paused;                             // where its needle stopped, as commanded
  Eigen::Vector3d tip_lps_mm = Eigen::Vector3d::Zero();  // the stylet's tip found on the scan
  Eigen::Vector3d tip_robot_mm = Eigen::Vector3d::Zero();
  double tip_offset_mm = 0.0;    // found tip − the model's, before the correction
  double path_rms_mm = 0.0;      // found path vs the corrected model path
  std::size_t path_points = 0;   // path points compared
  std::string model;             // the model the re-aim used, in words (refitted, or why not)
  std::vector<ReaimedAim> aims;  // this insertion first, then later targets in plan order
  std::string message;           // for a person: all of the above
  bool adopted = false;          // reaim took it
};

// What the server loads, searches and computes off the event thread (scan_needle).
struct NeedleScanJob {
  ConfirmationJob scan;  // the CT, the robot, a given registration
  std::optional<registration::Registration> session_registration;  // to compare the markers with
  std::uint32_t target_id = 0;
  Eigen::Vector3d target_robot_mm = Eigen::Vector3d::Zero();
  kinematics::Joints paused;  // where the needle stopped
  kinematics::Joints aimed;   // what the insertion was aimed with
  // The targets after it, not reached yet, in plan order: id, robot point, present aim.
  struct Later {
    std::uint32_t id = 0;
    Eigen::Vector3d robot_mm = Eigen::Vector3d::Zero();
    kinematics::Joints aimed;
  };
  std::vector<Later> later;
  // The model the plan aims with (its tissue, or none: the kinematics' path), the needle a refit
  // uses, and the targeting errors measured so far (confirmation rows) the refit adds the path to.
  std::optional<config::TissueProfile> aim_tissue;
  std::optional<config::TissueProfile> tissue;
  std::vector<compensation::TargetingRecord> records;
};
// The job: the scan measured as load_confirmation measures one, registered, the paused needle's
// tip chosen, the tissue refitted with its path, the rest re-aimed. needle_scanned (with
// Input::reaim) or needle_scan_failed (why).
Input scanNeedle(const NeedleScanJob& job);
// Its second half, from what measureConfirmation found on the scan (confirmation_measured, or
// confirmation_failed whose reason it passes on).
Input proposeReaim(const NeedleScanJob& job, const Input& measured);

}  // namespace ignav::workflow
