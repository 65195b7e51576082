// configs/worlds/*.yaml: a rod-in-tissue world. Every key is optional (the defaults of RodWorld);
// an unknown key is an error, so that a misspelt one is not silently the default.
#include <fstream>
#include <set>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "ignav/needle_world/rod_world.hpp"

namespace ignav::needle_world {
namespace {

struct Reader {
  const std::string& path;
  std::string error;

  // The node's keys must be among `known`; `where` names the node in errors.
  bool onlyKnown(const YAML::Node& node, const std::set<std::string>& known,
                 const std::string& where) {
    for (const auto& kv : node) {
      const auto key = kv.first.as<std::string>();
      if (!known.count(key)) {
        std::string names;
        for (const auto& k : known)
          names += (names.empty() ? "" : ", ") + k;
        error =
            fmt::format("{}: {}.{} is not a key of a world (known: {})", path, where, key, names);
        return false;
      }
    }
    return true;
  }
  void number(const YAML::Node& node, const char* key, const std::string& where, double& out,
              double scale = 1.0) {
    if (!error.empty() || !node[key]) return;
    try {
      out = node[key].as<double>() * scale;
    } catch (const YAML::Exception&) {
      error = fmt::format("{}: {}.{} must be a number", path, where, key);
    }
  }
};

}  // namespace

Expected<RodWorld> loadRodWorld(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{}: cannot read the world: {}", path, e.what()));
  }
  const YAML::Node w = root["world"];
  if (!w || !w.IsMap()) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{}: no 'world:' map (configs/worlds/*.yaml shows one)", path));
  }
  Reader r{path, {}};
  RodWorld out;
  if (!r.onlyKnown(w,
                   {"kind", "name", "source", "cannula_stiffness_nmm2", "stylet_stiffness_nmm2",
                    "cannula_tip_force_n", "stylet_tip_force_n", "stylet_grip_mm", "exit_play_bias",
                    "twist_deg_per_mm", "drag_shortfall_per_mm", "layers", "per_insertion", "seed"},
                   "world")) {
    return makeError(ErrorCode::kInvalidArgument, r.error);
  }
  const std::string kind = w["kind"] ? w["kind"].as<std::string>() : "rod_in_tissue";
  if (kind != "rod_in_tissue") {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{}: world.kind '{}' is not known (rod_in_tissue; the extended "
                                 "bicycle world is a tissue profile: --hidden-tissue)",
                                 path, kind));
  }
  out.name = w["name"] ? w["name"].as<std::string>() : path;
  out.source = w["source"] ? w["source"].as<std::string>() : "";
  r.number(w, "cannula_stiffness_nmm2", "world", out.cannula_stiffness_nmm2);
  r.number(w, "stylet_stiffness_nmm2", "world", out.stylet_stiffness_nmm2);
  r.number(w, "cannula_tip_force_n", "world", out.cannula_tip_force_n);
  r.number(w, "stylet_tip_force_n", "world", out.stylet_tip_force_n);
  r.number(w, "stylet_grip_mm", "world", out.stylet_grip_mm);
  r.number(w, "exit_play_bias", "world", out.exit_play_bias);
  r.number(w, "twist_deg_per_mm", "world", out.twist_rad_per_mm, M_PI / 180.0);
  r.number(w, "drag_shortfall_per_mm", "world", out.drag_shortfall_per_mm);
  if (w["seed"]) out.seed = w["seed"].as<std::uint64_t>();
  if (const YAML::Node layers = w["layers"]) {
    out.layers.clear();
    for (std::size_t i = 0; i < layers.size(); ++i) {
      const YAML::Node l = layers[i];
      const std::string where = fmt::format("world.layers[{}]", i);
      if (!l.IsMap() || !r.onlyKnown(l, {"name", "from_depth_mm", "stiffness_n_per_mm2"}, where)) {
        if (r.error.empty()) r.error = fmt::format("{}: {} must be a map", path, where);
        break;
      }
      TissueLayer layer;
      layer.name = l["name"] ? l["name"].as<std::string>() : fmt::format("layer {}", i + 1);
      r.number(l, "from_depth_mm", where, layer.from_depth_mm);
      r.number(l, "stiffness_n_per_mm2", where, layer.stiffness_n_per_mm2);
      out.layers.push_back(layer);
    }
  }
  if (const YAML::Node p = w["per_insertion"]) {
    if (r.onlyKnown(p, {"rotation_sd_deg", "backlash_mm", "exit_play_sd", "mount_sd_mm"},
                    "world.per_insertion")) {
      r.number(p, "rotation_sd_deg", "world.per_insertion", out.rotation_sd_rad, M_PI / 180.0);
      r.number(p, "backlash_mm", "world.per_insertion", out.backlash_mm);
      r.number(p, "exit_play_sd", "world.per_insertion", out.exit_play_sd);
      r.number(p, "mount_sd_mm", "world.per_insertion", out.mount_sd_mm);
    }
  }
  if (!r.error.empty()) return makeError(ErrorCode::kInvalidArgument, r.error);
  if (auto ok = checkWorld(out); !ok) {
    return makeError(ErrorCode::kInvalidArgument, path + ": " + ok.error().message);
  }
  return out;
}

}  // namespace ignav::needle_world
