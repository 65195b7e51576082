#include "ignav/config/robot_config.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

namespace ignav::config {
namespace {

// Reads one YAML mapping strictly; the first problem found is kept with its key path. Unknown
// keys are reported before missing ones: a misspelt key is the cause, the missing one a symptom.
class Section {
 public:
  Section(const YAML::Node& node, std::string path, std::string* error,
          std::initializer_list<const char*> keys)
      : node_(node), path_(std::move(path)), error_(error) {
    if (!node_ || !node_.IsMap()) {
      fail(path_, node_ ? "must be a mapping" : "is missing");
      return;
    }
    for (const auto& kv : node_) {
      const std::string key = kv.first.Scalar();
      if (std::find_if(keys.begin(), keys.end(), [&](const char* k) { return key == k; }) ==
          keys.end()) {
        std::string list;
        for (const char* k : keys)
          list += (list.empty() ? "" : ", ") + std::string(k);
        fail(path_ + "." + key, "unknown key; expected one of " + list);
        return;
      }
    }
  }

  Section child(const std::string& key, std::initializer_list<const char*> keys) {
    return Section(ok() ? node_[key] : YAML::Node(), path_ + "." + key, error_, keys);
  }

  double number(const std::string& key) {
    const YAML::Node n = scalar(key);
    if (!n) return 0.0;
    try {
      const double v = n.as<double>();
      if (std::isnan(v)) fail(path_ + "." + key, "is NaN; a number is required");
      return v;
    } catch (const YAML::Exception&) {
      fail(path_ + "." + key, "expected a number, got '" + n.Scalar() + "'");
      return 0.0;
    }
  }

  int integer(const std::string& key) {
    const YAML::Node n = scalar(key);
    if (!n) return 0;
    try {
      return n.as<int>();
    } catch (const YAML::Exception&) {
      fail(path_ + "." + key, "expected an integer, got '" + n.Scalar() + "'");
      return 0;
    }
  }

  std::string text(const std::string& key) {
    const YAML::Node n = scalar(key);
    return n ? n.Scalar() : std::string();
  }

  // One of the listed words; the error lists them.
  std::string choice(const std::string& key, const std::set<std::string>& allowed) {
    const std::string v = text(key);
    if (ok() && allowed.count(v) == 0) {
      std::string list;
      for (const std::string& a : allowed)
        list += (list.empty() ? "" : " | ") + a;
      fail(path_ + "." + key, "unknown value '" + v + "'; expected " + list);
    }
    return v;
  }

  bool has(const std::string& key) const { return ok() && node_[key]; }

  // For optional keys: the default when absent, else as number(key).
  double number(const std::string& key, double fallback) {
    return has(key) ? number(key) : fallback;
  }

  // Reports a value that parsed but is out of range.
  void require(bool condition, const std::string& key, const std::string& what) {
    if (!condition) fail(path_ + "." + key, what);
  }

  bool ok() const { return error_->empty(); }

 private:
  YAML::Node scalar(const std::string& key) {
    if (!ok()) return YAML::Node();
    const YAML::Node n = node_[key];
    if (!n) {
      fail(path_ + "." + key, "is missing");
      return YAML::Node();
    }
    if (!n.IsScalar()) {
      fail(path_ + "." + key, "must be a single value");
      return YAML::Node();
    }
    return n;
  }

  void fail(const std::string& where, const std::string& what) {
    if (error_->empty()) *error_ = where + ": " + what;
  }

  YAML::Node node_;
  std::string path_;
  std::string* error_;
};

// `robot.registration`: optional, and so is each key (defaults in settings.hpp).
void parseRegistration(Section& robot, RobotConfig& c) {
  auto& reg = c.registration;
  Section s =
      robot.child("registration",
                  {"scan_joints", "cannula_base_mm", "transform", "min_scale", "max_scale",
                   "max_fre_mm", "min_separation_mm", "min_spread_from_line_mm", "fle_mm",
                   "max_tre_mm", "fiducial_min_hu", "bead_min_volume_mm3", "bead_max_volume_mm3",
                   "bead_max_extent_mm", "max_match_residual_mm", "min_match_margin_mm"});
  if (s.has("scan_joints")) {
    Section j = s.child("scan_joints", {"theta_c_deg", "z_c_mm", "z_s_mm"});
    reg.scan.scan_joints.theta_c_rad = j.number("theta_c_deg") * M_PI / 180.0;
    reg.scan.scan_joints.z_c_mm = j.number("z_c_mm");
    reg.scan.scan_joints.z_s_mm = j.number("z_s_mm");
  }
  reg.scan.cannula_base_mm = s.number("cannula_base_mm", reg.scan.cannula_base_mm);
  if (s.has("transform")) {
    reg.kind = s.choice("transform", {"similarity", "rigid"}) == "rigid"
                   ? registration::TransformKind::kRigid
                   : registration::TransformKind::kSimilarity;
  }
  auto& limits = reg.limits;
  limits.min_scale = s.number("min_scale", limits.min_scale);
  limits.max_scale = s.number("max_scale", limits.max_scale);
  s.require(limits.min_scale > 0.0 && limits.min_scale <= limits.max_scale, "min_scale",
            "must be positive and at most max_scale");
  auto positive = [&s](const char* key, double& value) {
    value = s.number(key, value);
    s.require(value > 0.0 && std::isfinite(value), key, "must be positive");
  };
  positive("max_fre_mm", limits.max_fre_mm);
  positive("min_separation_mm", limits.min_separation_mm);
  positive("min_spread_from_line_mm", limits.min_spread_from_line_mm);
  positive("fle_mm", reg.fle_mm);
  positive("max_tre_mm", reg.max_tre_mm);
  auto& beads = reg.fiducials;
  beads.min_hu = s.number("fiducial_min_hu", beads.min_hu);
  s.require(std::isfinite(beads.min_hu), "fiducial_min_hu", "must be finite");
  positive("bead_min_volume_mm3", beads.min_volume_mm3);
  positive("bead_max_volume_mm3", beads.max_volume_mm3);
  s.require(beads.min_volume_mm3 <= beads.max_volume_mm3, "bead_min_volume_mm3",
            "must be at most bead_max_volume_mm3");
  positive("bead_max_extent_mm", beads.max_extent_mm);
  positive("max_match_residual_mm", beads.max_match_residual_mm);
  beads.min_match_margin_mm = s.number("min_match_margin_mm", beads.min_match_margin_mm);
  s.require(beads.min_match_margin_mm >= 0.0, "min_match_margin_mm", "must not be negative");
}

}  // namespace

Expected<RobotConfig> parseRobotConfig(const std::string& yaml_text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    return makeError(ErrorCode::kConfig, source + ": not valid YAML: " + e.what());
  }
  std::string error;
  RobotConfig c;
  if (!root.IsMap()) return makeError(ErrorCode::kConfig, source + ": robot: is missing");
  for (const auto& kv : root) {
    if (kv.first.Scalar() != "robot") {
      return makeError(ErrorCode::kConfig,
                       source + ": " + kv.first.Scalar() + ": unknown key; expected robot");
    }
  }
  Section r(root["robot"], "robot", &error,
            {"name", "stylet", "cannula", "model", "transmission", "registration"});
  c.name = r.text("name");

  Section stylet =
      r.child("stylet", {"radius_mm", "outer_diameter_mm", "travel_mm", "curved_length_mm"});
  c.instrument.stylet_radius_mm = stylet.number("radius_mm");
  c.instrument.stylet_outer_diameter_mm = stylet.number("outer_diameter_mm");
  c.instrument.stylet_travel_mm = stylet.number("travel_mm");
  c.instrument.stylet_curved_length_mm = stylet.number("curved_length_mm");

  Section cannula = r.child("cannula", {"inner_diameter_mm", "outer_diameter_mm", "travel_mm",
                                        "deflected_radius_mm", "fixed_offset_mm"});
  c.instrument.cannula_inner_diameter_mm = cannula.number("inner_diameter_mm");
  c.instrument.cannula_outer_diameter_mm = cannula.number("outer_diameter_mm");
  c.instrument.cannula_travel_mm = cannula.number("travel_mm");
  c.instrument.cannula_deflected_radius_mm = cannula.number("deflected_radius_mm");
  c.instrument.cannula_fixed_offset_mm = cannula.number("fixed_offset_mm");

  Section model = r.child("model", {"exit_offset"});
  const std::string offset = model.choice("exit_offset", {"lateral", "axial", "none"});
  c.instrument.exit_offset = offset == "axial"  ? kinematics::ExitOffset::kAxial
                             : offset == "none" ? kinematics::ExitOffset::kNone
                                                : kinematics::ExitOffset::kLateral;

  Section tx =
      r.child("transmission", {"motor_step_deg", "microsteps", "gearhead_ratio",
                               "cannula_gear_ratio", "stylet_gear_ratio", "lead_mm", "coupling"});
  c.transmission.motor_step_deg = tx.number("motor_step_deg");
  c.transmission.microsteps = tx.integer("microsteps");
  c.transmission.gearhead_ratio = tx.number("gearhead_ratio");
  c.transmission.cannula_gear_ratio = tx.number("cannula_gear_ratio");
  c.transmission.stylet_gear_ratio = tx.number("stylet_gear_ratio");
  c.transmission.lead_mm = tx.number("lead_mm");
  c.transmission.coupling = tx.choice("coupling", {"casing", "carried"}) == "carried"
                                ? actuation::Coupling::kCarried
                                : actuation::Coupling::kCasing;

  // Defaults that follow the geometry: the scan with the stylet fully deployed, and the base
  // marker at the lower end of the cannula's straight part (95 mm for the paper's instrument).
  c.registration.scan.scan_joints.z_s_mm = c.instrument.stylet_travel_mm;
  c.registration.scan.cannula_base_mm = c.instrument.cannula_fixed_offset_mm +
                                        c.instrument.stylet_travel_mm -
                                        c.instrument.stylet_curved_length_mm;
  if (r.has("registration")) parseRegistration(r, c);

  if (!error.empty()) return makeError(ErrorCode::kConfig, source + ": " + error);
  return c;
}

Expected<RobotConfig> loadRobotConfig(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return makeError(ErrorCode::kIo, path + ": cannot open robot configuration");
  std::ostringstream text;
  text << in.rdbuf();
  return parseRobotConfig(text.str(), path);
}

Expected<Robot> makeRobot(const RobotConfig& config, const std::string& source) {
  auto kin = kinematics::Kinematics::create(config.instrument);
  if (!kin) return makeError(kin.error().code, source + ": " + kin.error().message);
  auto tx = actuation::Transmission::create(config.transmission);
  if (!tx) return makeError(tx.error().code, source + ": " + tx.error().message);
  auto features = registration::featurePoints(*kin, config.registration.scan);
  if (!features) return makeError(features.error().code, source + ": " + features.error().message);
  return Robot{config, std::move(kin).value(), std::move(tx).value(), *features};
}

Expected<Robot> loadRobot(const std::string& path) {
  auto config = loadRobotConfig(path);
  if (!config) return config.error();
  return makeRobot(*config, path);
}

}  // namespace ignav::config
