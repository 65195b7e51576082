// Tissue profiles for the deflection prediction (configs/tissues.yaml): the needle model and
// named tissues with their slip parameters. Errors name the file and the key.
#pragma once

#include <map>
#include <string>

#include "ignav/core/expected.hpp"
#include "ignav/deflection/bicycle_model.hpp"

namespace ignav::config {

struct TissueProfile {
  std::string name;
  std::string source;  // where the numbers come from
  deflection::NeedleModel needle;
  deflection::Tissue tissue;
};

struct TissueProfiles {
  deflection::NeedleModel needle;
  std::map<std::string, TissueProfile> tissues;
};

Expected<TissueProfiles> loadTissueProfiles(const std::string& path);
// The named profile, or an error listing the names there are.
Expected<TissueProfile> tissueProfile(const TissueProfiles& profiles, const std::string& name);

}  // namespace ignav::config
