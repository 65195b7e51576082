// Which deposited seed belongs to which planned target: the assignment that minimises the total
// squared distance (assignment.hpp), with a maximum credible distance, refused when another
// assignment is nearly as good for the localisation uncertainty to tell them apart.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"

namespace ignav::verification {

// A planned target in the frame the seeds are given in (LPS for seeds found in a CT).
struct TargetPoint {
  std::uint32_t id = 0;
  Eigen::Vector3d mm = Eigen::Vector3d::Zero();
};

struct MatchOptions {
  // A seed farther than this from a target is not its seed (the paper's worst error was
  // 4.63 mm; its design threshold 5.2 mm).
  double max_distance_mm = 10.0;
  // Per-coordinate SD of a seed's localisation; the margin below is measured in units of what
  // this error does to the difference in total squared distance between two assignments.
  double localisation_sd_mm = 0.3;
  // Refuse when, for some target, the best assignment that gives it another seed (or none) is
  // worse by less than this many of those SDs.
  double min_margin_sd = 3.0;
  // More seeds than targets is refused unless allowed (after a person rejected what is not a
  // seed of this plan, or knowingly): then the seeds left over are reported as extra.
  bool allow_extra_seeds = false;
};

struct TargetMatch {
  std::uint32_t target_id = 0;
  std::optional<std::size_t> seed;  // index into the seeds given; none: the target is missing
  double distance_mm = std::numeric_limits<double>::quiet_NaN();  // NaN when missing
  // The cheapest assignment that changes this target's seed: the seed it would get there
  // (none: missing), how much more total squared distance it costs, and that in SDs of the
  // difference under localisation_sd_mm (infinite when there is no such assignment).
  std::optional<std::size_t> runner_up_seed;
  double runner_up_extra_mm2 = std::numeric_limits<double>::infinity();
  double runner_up_margin_sd = std::numeric_limits<double>::infinity();
};

struct SeedMatch {
  std::vector<TargetMatch> targets;                                // in the order given
  std::vector<std::size_t> missing_targets;                        // indices into the targets given
  std::vector<std::size_t> extra_seeds;                            // indices into the seeds given
  double total_squared_distance_mm2 = 0.0;                         // over the matched pairs
  double min_margin_sd = std::numeric_limits<double>::infinity();  // over the targets
  std::string summary;                                             // a sentence for a person
};

// Errors (each with a reason token): a non-finite point or bad option (invalid_argument,
// "non_finite" / "bad_option"), duplicate target ids ("duplicate_target"), no targets
// ("no_targets"), no seeds ("no_seeds"), more seeds than targets without allow_extra_seeds
// ("more_seeds_than_targets", naming the seeds the best assignment leaves over), an ambiguous
// assignment ("ambiguous_match", naming the targets and seeds that could be exchanged and by how
// little). Missing targets and extra seeds beyond max_distance_mm are results, not errors.
Expected<SeedMatch> matchSeeds(const std::vector<TargetPoint>& targets,
                               const std::vector<Eigen::Vector3d>& seeds_mm,
                               const MatchOptions& options = {});

}  // namespace ignav::verification
