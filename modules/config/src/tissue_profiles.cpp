#include "ignav/config/tissue_profiles.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>

namespace ignav::config {

Expected<TissueProfiles> loadTissueProfiles(const std::string& path) {
  auto bad = [&](const std::string& key, const std::string& why) {
    return makeError(ErrorCode::kInvalidArgument, path + ": " + key + ": " + why);
  };
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    return makeError(ErrorCode::kIo, path + ": " + e.what());
  }
  TissueProfiles out;
  auto number = [&](const YAML::Node& n, const std::string& key, double& value) -> Status {
    if (!n) return Ok{};
    try {
      value = n.as<double>();
    } catch (const YAML::Exception&) {
      return bad(key, "is not a number");
    }
    if (!std::isfinite(value)) return bad(key, "must be finite");
    return Ok{};
  };
  if (auto ok = number(root["needle"]["curvature_per_mm"], "needle.curvature_per_mm",
                       out.needle.curvature_per_mm);
      !ok) {
    return ok.error();
  }
  if (auto ok =
          number(root["needle"]["wheelbase_mm"], "needle.wheelbase_mm", out.needle.wheelbase_mm);
      !ok) {
    return ok.error();
  }
  if (!(out.needle.wheelbase_mm > 0)) return bad("needle.wheelbase_mm", "must be positive");
  const YAML::Node tissues = root["tissues"];
  if (!tissues || !tissues.IsMap() || tissues.size() == 0) return bad("tissues", "is missing");
  for (const auto& kv : tissues) {
    TissueProfile p;
    p.name = kv.first.Scalar();
    p.needle = out.needle;
    const std::string key = "tissues." + p.name;
    for (const auto& field : kv.second) {
      const std::string f = field.first.Scalar();
      if (f != "lambda1" && f != "lambda2" && f != "curvature_per_mm" && f != "source") {
        return bad(key + "." + f,
                   "unknown key; expected lambda1, lambda2, curvature_per_mm, source");
      }
    }
    if (!kv.second["lambda1"] || !kv.second["lambda2"]) {
      return bad(key, "needs lambda1 and lambda2");
    }
    if (auto ok = number(kv.second["lambda1"], key + ".lambda1", p.tissue.lambda1); !ok) {
      return ok.error();
    }
    if (auto ok = number(kv.second["lambda2"], key + ".lambda2", p.tissue.lambda2); !ok) {
      return ok.error();
    }
    // A profile fitted with its curvature carries the needle's k along (it overrides needle's).
    if (auto ok = number(kv.second["curvature_per_mm"], key + ".curvature_per_mm",
                         p.needle.curvature_per_mm);
        !ok) {
      return ok.error();
    }
    if (kv.second["source"]) p.source = kv.second["source"].as<std::string>();
    const auto admissible = deflection::checkAdmissible(p.needle, p.tissue);
    if (!admissible.admissible) return bad(key, admissible.reason);
    out.tissues[p.name] = p;
  }
  return out;
}

Expected<TissueProfile> tissueProfile(const TissueProfiles& profiles, const std::string& name) {
  const auto it = profiles.tissues.find(name);
  if (it != profiles.tissues.end()) return it->second;
  std::string names;
  for (const auto& [n, p] : profiles.tissues)
    names += (names.empty() ? "" : ", ") + n;
  return makeError(ErrorCode::kInvalidArgument,
                   "tissue '" + name + "' is not a profile (there are: " + names + ")");
}

}  // namespace ignav::config
