// Deposited seeds in a confirmation CT (metal cylinders ~3 mm long, ~0.8 mm wide: the paper's
// dummies), found automatically: one pass thresholds the volume, bright voxels are grouped by
// 26-connectivity (a group rejected as too much for one seed is cut at its intensity valleys into
// seeds where it can be), and each group gets an intensity-weighted centroid above its local
// background over the group and a partial-volume shell (sub-voxel), and a principal axis, length
// and width from the second moments of the weights clear of the noise (less a voxel's own spread).
// Groups that cannot be a seed (too little or too much metal, too wide or too long, a robot marker)
// are listed with the reason.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::verification {

struct SeedSearch {
  // Bright voxels: at or above this. Seeds far thinner than a voxel show only part of their
  // metal (a 0.8 mm seed lying across 1.25 mm slices fills as little as an eighth of a voxel), so
  // this sits well below the metal's own value; cortical bone passes it and is rejected by size.
  double min_hu = 500.0;
  // The metal in a group: the sum of (HU - background) * voxel volume. A 3 x 0.8 mm seed of
  // 7000 HU holds ~10,500 HU·mm³ whatever the partial volume; a calcification or a speck holds
  // far less, a 1.5 mm bead (3000 HU) ~42,000 but it is too wide.
  double min_metal_hu_mm3 = 2000.0;
  double max_metal_hu_mm3 = 40000.0;
  // Shape from the second moments (a uniform rod of length L has variance L²/12 along it, a disc
  // of diameter d has d²/16 across), which also hold the scanner's blur, and for a seed thinner
  // than a voxel the voxels' aliasing: a 0.8 mm seed can measure 1.8-2.1 mm wide. The paper's
  // seeds are 3 mm long, clinical ones 4.5 mm. A seed is a rod: its variance along the axis is
  // at least min_elongation times the larger one across (a bead's or a speck's is about 1).
  double min_length_mm = 1.5;
  double max_length_mm = 6.0;
  double max_width_mm = 3.0;
  double min_elongation = 1.5;
  // A group whose voxels reach this far is not refined at all (bone, the cannula, the stylet).
  double max_extent_mm = 12.0;
  // The robot's markers (LPS): a group whose centre lies within marker_exclusion_mm of one is
  // the marker, not a seed.
  std::vector<Eigen::Vector3d> markers_lps_mm;
  double marker_exclusion_mm = 4.0;
  // Partial-volume voxels within this many voxels (Chebyshev) of a group are weighed with it;
  // the background is the median of the ring out to background_voxels.
  int shell_voxels = 2;
  int background_voxels = 4;
  // Guards a threshold set into soft tissue or bone.
  std::size_t max_bright_voxels = 4'000'000;
};

struct SeedCandidate {
  Eigen::Vector3d centroid_lps_mm = Eigen::Vector3d::Zero();
  // Unit principal axis (its sign is arbitrary; the largest component is made positive).
  Eigen::Vector3d axis_lps = Eigen::Vector3d::UnitZ();
  double length_mm = 0.0;  // sqrt(12 × variance along the axis), less the voxel's spread
  double width_mm = 0.0;   // 4 × sqrt(larger variance across), less the voxel's spread
  double metal_hu_mm3 = 0.0;
  double peak_hu = 0.0;
  double background_hu = 0.0;   // median of the ring around the group
  double noise_hu = 0.0;        // the ring's SD (from its median absolute deviation)
  double extent_mm = 0.0;       // largest side of the thresholded group's box
  std::size_t voxel_count = 0;  // voxels at or above min_hu
  double elongation = 0.0;      // variance along the axis / the larger across
  // Seeds whose images touched form one bright group; it is cut at its intensity valleys
  // (the threshold raised within it until its cores stand apart) when every part is a seed:
  // how many seeds the group held (0: the seed was a group of its own) and the level they parted
  // at.
  std::size_t touching = 0;
  double valley_hu = 0.0;
  // Empty for a seed; otherwise a token (too_little_metal, too_much_metal, too_wide, too_short,
  // too_long, not_elongated, marker, no_contrast) and a sentence.
  std::string reason;
  std::string rejected;
};

struct SeedDetection {
  std::vector<SeedCandidate> seeds;     // in scan order (slice, row, column of a first voxel)
  std::vector<SeedCandidate> rejected;  // at most 64, the rest counted
  std::size_t rejected_not_listed = 0;
  std::size_t bright_voxels = 0;
  std::size_t groups = 0;
  std::string summary;  // a sentence for a person
};

// Errors: a bad search (NaN, ranges the wrong way round, negative shells), a volume whose buffer
// does not match its geometry, more than max_bright_voxels bright voxels. Finding nothing is not
// an error (the summary says so; matching refuses no seeds).
Expected<SeedDetection> findSeeds(const volume::Volume& volume, const SeedSearch& search = {});

}  // namespace ignav::verification
