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

}  // namespace ignav::workflow
