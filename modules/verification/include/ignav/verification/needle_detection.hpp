// The needle in a confirmation CT, when the scan was taken with it still in (issue 23): the
// stylet's tip with sub-voxel accuracy, and the centreline of the visible cannula and stylet.
//
// A needle is a bright group (as the seed search groups them) at least min_length_mm long. Its
// centreline is tracked from the end the needle comes in by (the least deep along the insertion
// direction) in steps of step_mm: each step the weighted centroid of the group's voxels in a slab
// across the current direction. The tip is where the metal ends, measured along the wire's own
// axis at its end and independent of the blur and the partial volume: the metal per mm behind
// the end (a plateau of stylet) and the metal past a reference point give tip = reference +
// metal past / metal per mm. Across the axis, the centreline's last millimetres are fitted with a
// parabola and carried to that depth.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::verification {

struct NeedleSearch {
  // The way the needle goes in (LPS, need not be unit): the robot's −Z through the registration.
  Eigen::Vector3d insertion_lps = Eigen::Vector3d::UnitZ();
  double min_hu = 500.0;         // bright voxels, as the seed search's
  double min_length_mm = 12.0;   // shorter is a seed or a speck (the seed search's max extent)
  double max_diameter_mm = 4.0;  // a wire: wider at its tip is bone or a clump of seeds
  double tube_radius_mm = 2.5;   // voxels this close to the axis are weighed at the tip
  double step_mm = 1.0;          // centreline spacing
  double plateau_mm = 2.5;       // of stylet behind the reference point, for the metal per mm
  // The needle comes in along the insertion: its first 10 mm within this angle of it. A wire, a
  // vessel's calcified wall or a rib's edge lying across is no needle of this robot.
  double max_entry_angle_deg = 30.0;
  std::vector<Eigen::Vector3d> markers_lps_mm;  // groups within marker_exclusion_mm: markers
  double marker_exclusion_mm = 4.0;
  std::size_t max_bright_voxels = 4'000'000;
};

struct FoundNeedle {
  Eigen::Vector3d tip_lps_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction_lps = Eigen::Vector3d::UnitZ();  // at the tip, onwards (unit)
  // From where the needle enters the scan to the tip, about step_mm apart; the last is the tip.
  std::vector<Eigen::Vector3d> centreline_lps_mm;
  double visible_length_mm = 0.0;  // along the centreline
  double metal_per_mm = 0.0;       // HU·mm² behind the tip (the stylet's cross-section × HU)
  double tip_diameter_mm = 0.0;    // 4 × the RMS distance of the tip's metal from its axis
  double background_hu = 0.0;
};

struct NeedleDetection {
  std::vector<FoundNeedle> needles;  // deepest tip first
  std::size_t groups = 0;            // bright groups looked at
  std::string summary;               // a sentence for a person
};

// Errors: a bad search (non-finite or zero insertion direction, lengths not positive), a volume
// whose buffer does not match its geometry, too many bright voxels. No needle is not an error.
Expected<NeedleDetection> findNeedles(const volume::Volume& volume, const NeedleSearch& search);

}  // namespace ignav::verification
