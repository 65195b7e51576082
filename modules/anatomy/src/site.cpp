// A site's roles for structures by name (site.hpp).
#include "ignav/anatomy/site.hpp"

#include <cmath>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

namespace ignav::anatomy {
const SiteRole* Site::roleFor(const std::string& structure_name) const {
  for (const auto& r : roles) {
    if (namesMatch(r.name, structure_name)) return &r;
    for (const auto& alias : r.aliases)
      if (namesMatch(alias, structure_name)) return &r;
  }
  return nullptr;
}

Expected<Site> readSite(const std::string& path) {
  auto bad = [&](const std::string& what) {
    return makeError(ErrorCode::kConfig, path + ": " + what, "bad_site");
  };
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    return bad(e.what());
  }
  Site site;
  try {
    if (root["site"]) site.name = root["site"].as<std::string>();
    const auto list = root["structures"];
    if (!list || !list.IsSequence()) return bad("'structures' must be a list");
    for (std::size_t n = 0; n < list.size(); ++n) {
      const auto e = list[n];
      const std::string where = fmt::format("structures[{}]", n);
      SiteRole r;
      if (!e["name"]) return bad(where + ": 'name' is missing");
      r.name = e["name"].as<std::string>();
      const std::string role = e["role"] ? e["role"].as<std::string>() : "";
      const auto parsed = roleNamed(role);
      if (!parsed)
        return bad(where + " (" + r.name + "): role '" + role +
                   "' is none of target, avoid, shown");
      r.role = *parsed;
      if (e["margin_mm"]) r.margin_mm = e["margin_mm"].as<double>();
      if (!std::isfinite(r.margin_mm) || r.margin_mm < 0.0 || r.margin_mm > kMaxMargin_mm) {
        return bad(fmt::format("{} ({}): margin_mm {} is outside 0-{:g} mm", where, r.name,
                               r.margin_mm, kMaxMargin_mm));
      }
      if (r.role == Role::kAvoid && !e["margin_mm"]) {
        return bad(where + " (" + r.name + "): an avoided structure needs margin_mm");
      }
      if (e["aliases"]) r.aliases = e["aliases"].as<std::vector<std::string>>();
      if (site.roleFor(r.name)) return bad(where + ": '" + r.name + "' is named twice");
      site.roles.push_back(std::move(r));
    }
  } catch (const YAML::Exception& e) {
    return bad(e.what());
  }
  return site;
}

void applySite(const Site& site, StructureSet& set) {
  for (auto& s : set.structures) {
    if (const auto* r = site.roleFor(s.name)) {
      s.role = r->role;
      s.margin_mm = r->margin_mm;
    }
  }
}

}  // namespace ignav::anatomy
