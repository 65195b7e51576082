// A site's roles for structures by name (issue 41): configs/sites/*.yaml, e.g.
//   structures:
//     - {name: urethra, role: avoid, margin_mm: 3}
//     - {name: prostate, role: target, aliases: [CTV, gland]}
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "ignav/anatomy/structures.hpp"
#include "ignav/core/expected.hpp"

namespace ignav::anatomy {

// The largest margin a site or a command may give: a structure's distance field reaches 15 mm
// (the server's), and the uncertainty at the needle needs room below that.
constexpr double kMaxMargin_mm = 10.0;

struct SiteRole {
  std::string name;
  std::vector<std::string> aliases;
  Role role = Role::kShown;
  double margin_mm = 0.0;
};

struct Site {
  std::string name;  // the file's `site:`
  std::vector<SiteRole> roles;
  // The entry for a structure's name or one of its aliases, ignoring case.
  const SiteRole* roleFor(const std::string& structure_name) const;
};

// Errors name the file and the entry (margins finite, 0-10 mm; avoid needs a margin).
Expected<Site> readSite(const std::string& path);
// Every structure the site names gets its role and margin; the rest are shown only.
void applySite(const Site& site, StructureSet& set);

}  // namespace ignav::anatomy
