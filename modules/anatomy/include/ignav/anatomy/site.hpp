// A site's roles for structures by name and where it lets the robot stand (issue 41):
// configs/sites/*.yaml, e.g.
//   structures:
//     - {name: urethra, role: avoid, margin_mm: 3}
//     - {name: prostate, role: target, aliases: [CTV, gland]}
//   placement: {approach: inferior, max_tilt_deg: 20, max_shift_mm: 20}
//   dosimetry: {seed_models: ../seeds, seed_model: oncura_6711, prescription_Gy: 145, ...}
// and a structure's dose limits for seed plans (issue 42): {..., dose_limits: {d10_percent: 150}}
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "ignav/anatomy/structures.hpp"
#include "ignav/core/expected.hpp"
#include "ignav/dosimetry/organ_limits.hpp"

namespace ignav::anatomy {

// The largest margin a site or a command may give: a structure's distance field reaches 15 mm
// (the server's), and the uncertainty at the needle needs room below that.
constexpr double kMaxMargin_mm = 10.0;

// Where a site lets the robot stand (its `placement:` block; place_robot). The needle goes into
// the patient along `insertion_lps` (a unit direction; from the side `approach` names, e.g.
// inferior: from the perineum towards the head, +S) give or take `max_tilt_deg`; its axis passes
// within `max_shift_mm` of the target's centroid; the robot's origin (the cannula's proximal end,
// where its casing holds it) stays at least `min_skin_distance_mm` outside the skin, which is
// where the CT first shows `skin_hu` or more along the axis.
struct PlacementLimits {
  std::string approach = "inferior";
  Eigen::Vector3d insertion_lps{0.0, 0.0, 1.0};
  double max_tilt_deg = 20.0;
  double max_shift_mm = 20.0;
  double min_skin_distance_mm = 60.0;
  double skin_hu = -300.0;
  // Errors name the field: tilt outside 0-45°, shift outside 0-60 mm, a skin distance outside
  // 0-300 mm, a non-finite skin_hu.
  Status validate() const;
};
// The direction a needle coming from `side` goes in (LPS): superior, inferior, anterior,
// posterior, left, right; nullopt for another word.
std::optional<Eigen::Vector3d> insertionFrom(std::string_view side);

struct SiteRole {
  std::string name;
  std::vector<std::string> aliases;
  Role role = Role::kShown;
  double margin_mm = 0.0;
  dosimetry::OrganLimits dose_limits;  // what a seed plan may give it (NaN: not limited)
};

// A site's seed plans (its `dosimetry:` block; plan_seeds): where the seed models are (a folder
// of <name>.yaml, relative to the site file) and which exist there, and the plan's defaults.
constexpr double kMinSeedSpacing_mm = 2.0, kMaxSeedSpacing_mm = 15.0;
struct SiteDosimetry {
  std::string seed_models_dir;           // absolute once read
  std::vector<std::string> seed_models;  // the names found there, sorted
  std::string seed_model;                // the default
  double prescription_Gy = 145.0;
  double strength_U = 0.5;  // every seed's air-kerma strength
  double spacing_mm = 5.0;  // the candidates' lattice
};

struct Site {
  std::string name;  // the file's `site:`
  std::vector<SiteRole> roles;
  PlacementLimits placement;  // the defaults when the file has no `placement:`
  std::optional<SiteDosimetry> dosimetry;
  // The entry for a structure's name or one of its aliases, ignoring case.
  const SiteRole* roleFor(const std::string& structure_name) const;
};

// Errors name the file and the entry (margins finite, 0-10 mm; avoid needs a margin; placement's
// limits in range, its approach a side; dose limits positive; the seed models' folder readable,
// the default model one of them, the prescription positive, the strength and spacing in range).
Expected<Site> readSite(const std::string& path);
// Every structure the site names gets its role and margin; the rest are shown only.
void applySite(const Site& site, StructureSet& set);

}  // namespace ignav::anatomy
