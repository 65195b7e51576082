// A site's roles for structures by name (site.hpp).
#include "ignav/anatomy/site.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "ignav/dosimetry/seed_plan.hpp"

namespace ignav::anatomy {

Status PlacementLimits::validate() const {
  auto bad = [](const std::string& what) {
    return makeError(ErrorCode::kInvalidArgument, "placement." + what, "bad_placement");
  };
  if (!insertion_lps.allFinite() || std::abs(insertion_lps.norm() - 1.0) > 1e-6)
    return bad("insertion_lps must be a unit direction");
  if (!std::isfinite(max_tilt_deg) || max_tilt_deg < 0.0 || max_tilt_deg > 45.0)
    return bad(fmt::format("max_tilt_deg = {} is outside 0-45°", max_tilt_deg));
  if (!std::isfinite(max_shift_mm) || max_shift_mm < 0.0 || max_shift_mm > 60.0)
    return bad(fmt::format("max_shift_mm = {} is outside 0-60 mm", max_shift_mm));
  if (!std::isfinite(min_skin_distance_mm) || min_skin_distance_mm < 0.0 ||
      min_skin_distance_mm > 300.0)
    return bad(fmt::format("min_skin_distance_mm = {} is outside 0-300 mm", min_skin_distance_mm));
  if (!std::isfinite(skin_hu)) return bad("skin_hu must be finite");
  return Ok{};
}

std::optional<Eigen::Vector3d> insertionFrom(std::string_view side) {
  // LPS: +x left, +y posterior, +z superior; a needle from one side goes towards the other.
  if (namesMatch(side, "inferior")) return Eigen::Vector3d(0, 0, 1);
  if (namesMatch(side, "superior")) return Eigen::Vector3d(0, 0, -1);
  if (namesMatch(side, "anterior")) return Eigen::Vector3d(0, 1, 0);
  if (namesMatch(side, "posterior")) return Eigen::Vector3d(0, -1, 0);
  if (namesMatch(side, "right")) return Eigen::Vector3d(1, 0, 0);
  if (namesMatch(side, "left")) return Eigen::Vector3d(-1, 0, 0);
  return std::nullopt;
}

const SiteRole* Site::roleFor(const std::string& structure_name) const {
  for (const auto& r : roles) {
    if (namesMatch(r.name, structure_name)) return &r;
    for (const auto& alias : r.aliases)
      if (namesMatch(alias, structure_name)) return &r;
  }
  return nullptr;
}

namespace {

// A structure's `dose_limits: {d10_percent: 150, d2cc_percent: 100, dmax_percent: 300}`; "" or
// what is wrong.
std::string readDoseLimits(const YAML::Node& node, dosimetry::OrganLimits& limits) {
  if (!node.IsMap()) return "dose_limits must be a map of d10_percent, d2cc_percent, dmax_percent";
  for (const auto& kv : node) {
    const auto key = kv.first.as<std::string>();
    double* field = key == "d10_percent"    ? &limits.d10_percent
                    : key == "d2cc_percent" ? &limits.d2cc_percent
                    : key == "dmax_percent" ? &limits.dmax_percent
                                            : nullptr;
    if (!field) return "dose_limits." + key + " is none of d10_percent, d2cc_percent, dmax_percent";
    *field = kv.second.as<double>();
    if (!std::isfinite(*field) || *field <= 0.0 || *field > 1000.0)
      return fmt::format("dose_limits.{} = {} is outside 0-1000 %", key, *field);
  }
  return "";
}

// The `dosimetry:` block; "" or what is wrong.
std::string readDosimetry(const YAML::Node& node, const std::string& site_path, SiteDosimetry& d) {
  namespace fs = std::filesystem;
  if (!node["seed_models"]) return "dosimetry.seed_models (the seed models' folder) is missing";
  fs::path dir = node["seed_models"].as<std::string>();
  if (dir.is_relative()) dir = fs::path(site_path).parent_path() / dir;
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    return "dosimetry.seed_models: '" + dir.string() + "' is not a folder";
  d.seed_models_dir = fs::absolute(dir, ec).lexically_normal().string();
  for (const auto& entry : fs::directory_iterator(dir, ec))
    if (entry.path().extension() == ".yaml") d.seed_models.push_back(entry.path().stem().string());
  std::sort(d.seed_models.begin(), d.seed_models.end());
  if (d.seed_models.empty()) return "dosimetry.seed_models: no <model>.yaml in " + dir.string();
  if (node["seed_model"]) d.seed_model = node["seed_model"].as<std::string>();
  if (std::find(d.seed_models.begin(), d.seed_models.end(), d.seed_model) == d.seed_models.end())
    return fmt::format("dosimetry.seed_model '{}' is none of {}", d.seed_model,
                       fmt::join(d.seed_models, ", "));
  if (node["prescription_Gy"]) d.prescription_Gy = node["prescription_Gy"].as<double>();
  if (node["strength_U"]) d.strength_U = node["strength_U"].as<double>();
  if (node["spacing_mm"]) d.spacing_mm = node["spacing_mm"].as<double>();
  if (!std::isfinite(d.prescription_Gy) || d.prescription_Gy <= 0.0 || d.prescription_Gy > 1000.0)
    return fmt::format("dosimetry.prescription_Gy = {} is outside 0-1000 Gy", d.prescription_Gy);
  if (!(d.strength_U >= dosimetry::kMinSeedStrength_U &&
        d.strength_U <= dosimetry::kMaxSeedStrength_U))
    return fmt::format("dosimetry.strength_U = {} is outside {:g}-{:g} U", d.strength_U,
                       dosimetry::kMinSeedStrength_U, dosimetry::kMaxSeedStrength_U);
  if (!(d.spacing_mm >= kMinSeedSpacing_mm && d.spacing_mm <= kMaxSeedSpacing_mm))
    return fmt::format("dosimetry.spacing_mm = {} is outside {:g}-{:g} mm", d.spacing_mm,
                       kMinSeedSpacing_mm, kMaxSeedSpacing_mm);
  return "";
}

}  // namespace

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
      if (e["dose_limits"]) {
        if (const auto why = readDoseLimits(e["dose_limits"], r.dose_limits); !why.empty())
          return bad(where + " (" + r.name + "): " + why);
      }
      if (e["aliases"]) r.aliases = e["aliases"].as<std::vector<std::string>>();
      if (site.roleFor(r.name)) return bad(where + ": '" + r.name + "' is named twice");
      site.roles.push_back(std::move(r));
    }
    if (const auto p = root["placement"]) {
      auto& limits = site.placement;
      if (p["approach"]) {
        limits.approach = p["approach"].as<std::string>();
        const auto direction = insertionFrom(limits.approach);
        if (!direction)
          return bad("placement.approach '" + limits.approach +
                     "' is none of inferior, superior, anterior, posterior, left, right");
        limits.insertion_lps = *direction;
      }
      if (p["max_tilt_deg"]) limits.max_tilt_deg = p["max_tilt_deg"].as<double>();
      if (p["max_shift_mm"]) limits.max_shift_mm = p["max_shift_mm"].as<double>();
      if (p["min_skin_distance_mm"])
        limits.min_skin_distance_mm = p["min_skin_distance_mm"].as<double>();
      if (p["skin_hu"]) limits.skin_hu = p["skin_hu"].as<double>();
      if (auto valid = limits.validate(); !valid.ok()) return bad(valid.error().message);
    }
    if (const auto d = root["dosimetry"]) {
      SiteDosimetry dosimetry;
      if (const auto why = readDosimetry(d, path, dosimetry); !why.empty()) return bad(why);
      site.dosimetry = std::move(dosimetry);
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
