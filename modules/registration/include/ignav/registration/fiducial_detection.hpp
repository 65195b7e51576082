// Automatic fiducial localisation on a CT: bright voxels are thresholded and clustered (PCL
// Euclidean clustering), each bead-sized cluster gets a sub-voxel centroid weighted by its HU
// above the local background, and the candidates are matched to the model points by their
// mutual distances, so the user confirms instead of clicking.
//
// The markers must be separate from other metal by more than a voxel diagonal: a bead touching
// the needle merges with it into one cluster that is too long to be a bead.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::registration {

struct FiducialSearch {
  double min_hu = 1500.0;  // metal beads; above most cortical bone
  // A bead-sized cluster: smaller is noise or a speck of bone, larger is bone, a rod, the needle.
  double min_volume_mm3 = 1.0;
  double max_volume_mm3 = 150.0;
  double max_extent_mm = 10.0;
  std::size_t expect = 3;  // how many markers the user placed (without model points)
  // A match whose RMS mutual-distance residual exceeds this is not offered.
  double max_match_residual_mm = 2.0;
  // ... nor one whose next-best assignment is within this much of it: an ambiguous choice.
  double min_match_margin_mm = 0.5;
  // Guards a threshold set into soft tissue: more bright voxels than this is an error.
  std::size_t max_bright_voxels = 1'000'000;
};

struct FiducialCandidate {
  Eigen::Vector3d centroid_lps_mm = Eigen::Vector3d::Zero();
  std::size_t voxel_count = 0;  // voxels at or above min_hu
  double volume_mm3 = 0.0;
  double extent_mm = 0.0;  // largest dimension of the thresholded cluster
  double peak_hu = 0.0;
  double background_hu = 0.0;  // median HU around the cluster
  std::string rejected;        // why it is not bead-like; empty when it is
};

struct FiducialMatch {
  // candidate index per model point, in model order
  std::vector<std::size_t> candidate;
  // |detected distance - model distance| per model pair (0-1, 0-2, 1-2, ...)
  std::vector<double> distance_residuals_mm;
  double rms_residual_mm = 0.0;
  // The best assignment that differs from this one: how distinct the choice is (inf if none).
  double runner_up_rms_mm = 0.0;
};

struct FiducialDetection {
  std::vector<FiducialCandidate> candidates;  // largest first
  std::size_t bright_voxels = 0;
  std::optional<FiducialMatch> match;
  std::string summary;  // a sentence for a person: what was found and how sure
};

// model_points_mm: the markers' positions in another frame (robot), in the order a match
// should report; empty to detect without matching (then a choice is made only when exactly
// `expect` bead-like candidates exist). Errors for a bad search (NaN, min > max) or too many
// bright voxels; finding nothing is not an error (the summary says so).
Expected<FiducialDetection> findFiducials(const volume::Volume& volume,
                                          const FiducialSearch& search,
                                          const std::vector<Eigen::Vector3d>& model_points_mm);

// The assignment of candidate positions to model points that best preserves the model's
// mutual distances (scale 1). Errors when fewer candidates than model points
// (too_few_candidates), when even the best assignment's RMS residual exceeds max_residual_mm
// (no_match), or when the runner-up is within min_margin_mm of it (ambiguous_match).
Expected<FiducialMatch> matchByDistances(const std::vector<Eigen::Vector3d>& candidates_mm,
                                         const std::vector<Eigen::Vector3d>& model_points_mm,
                                         double max_residual_mm, double min_margin_mm);

}  // namespace ignav::registration
