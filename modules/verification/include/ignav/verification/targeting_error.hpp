// Targeting error as the paper's Table V reports it: per target the error of the deposited seed
// (actual - planned) in the robot frame and in LPS, its norm, the split along the insertion axis
// (the robot's z; +z points out of the body, MODEL.md §2) and across it, and summary statistics.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/verification/seed_matching.hpp"

namespace ignav::verification {

// n, mean, sample SD (n - 1 in the denominator; 0 when n < 2), min, max and RMS of a list.
struct Stats {
  std::size_t count = 0;
  double mean = 0.0;
  double sd_sample = 0.0;
  double min = 0.0;
  double max = 0.0;
  double rms = 0.0;
};
Stats summarize(const std::vector<double>& values);

struct PlannedTarget {
  std::uint32_t id = 0;
  Eigen::Vector3d robot_mm = Eigen::Vector3d::Zero();
};

struct TargetError {
  std::uint32_t target_id = 0;
  Eigen::Vector3d planned_robot_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d actual_robot_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d planned_lps_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d actual_lps_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d error_robot_mm = Eigen::Vector3d::Zero();  // actual - planned
  Eigen::Vector3d error_lps_mm = Eigen::Vector3d::Zero();
  double error_mm = 0.0;  // |error_robot_mm|
  // Across the insertion axis: sqrt(ex² + ey²) in the robot frame, and that vector split into
  // radial r̂ (the planned target's direction from the cannula axis, i.e. within the stylet's
  // plane, where the needle bends; +y, the θc = 0 direction, for a target on the axis) and
  // tangential ẑ × r̂ (normal to the stylet's plane, counter-clockwise about +z), both signed.
  double lateral_mm = 0.0;
  double radial_mm = 0.0;
  double tangential_mm = 0.0;
  // Along it, signed: + when the seed lies deeper than planned (= -ez).
  double depth_mm = 0.0;
};

struct ErrorSummary {
  Stats error;                          // the norms
  Stats lateral;                        // magnitudes
  Stats depth;                          // signed (mean = the depth bias)
  Stats abs_depth;                      // magnitudes
  std::array<Stats, 3> abs_axis_robot;  // |ex|, |ey|, |ez| in the robot frame
  std::array<Stats, 3> abs_axis_lps;    // |eL|, |eP|, |eS|
};
ErrorSummary summarizeErrors(const std::vector<TargetError>& errors);

// One seed position (LPS) per target: the errors, in the targets' order, with
// image_to_robot (p_robot = M · p_lps, homogeneous; a similarity: its scale enters the
// robot-frame vector, as it entered the plan). Errors for a matrix that is not finite, not
// affine or singular, or for a non-finite point.
Expected<TargetError> targetError(const PlannedTarget& target, const Eigen::Vector3d& actual_lps_mm,
                                  const Eigen::Matrix4d& image_to_robot);

struct Verification {
  SeedMatch match;
  std::vector<TargetError> errors;  // matched targets, in the targets' order
  ErrorSummary summary;             // over the matched targets
  std::string text;                 // a sentence: mean ± SD (sample), max, min, RMS, missing
};

// Everything from the planned targets (robot frame) and the seeds found (LPS): the targets are
// mapped to LPS, matched (matchSeeds, in LPS, where the localisation uncertainty is), and each
// pair's error measured. Errors as matchSeeds and targetError.
Expected<Verification> verifyTargeting(const std::vector<PlannedTarget>& targets,
                                       const std::vector<Eigen::Vector3d>& seeds_lps_mm,
                                       const Eigen::Matrix4d& image_to_robot,
                                       const MatchOptions& options = {});

}  // namespace ignav::verification
