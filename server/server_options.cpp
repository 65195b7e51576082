#include "server_options.hpp"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "ignav/igtl/brp.hpp"
#include "ignav/protocol/topics.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::server {
namespace {

namespace fs = std::filesystem;

struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// What a setting must be, for the message that names a value of the wrong kind.
template <typename T>
const char* expectedKind() {
  if constexpr (std::is_same_v<T, bool>) return "true or false";
  if constexpr (std::is_same_v<T, std::string>) return "a text";
  if constexpr (std::is_same_v<T, std::vector<std::string>>) return "a list of texts";
  if constexpr (std::is_floating_point_v<T>) return "a number";
  if constexpr (std::is_integral_v<T> && std::is_unsigned_v<T>) {
    if constexpr (sizeof(T) == 4) return "a whole number within 0..4294967295";
    return "a whole number, 0 or more";
  }
  return "a whole number";
}

// A setting's value as T, or a ConfigError naming the file, the key and the value as written
// (yaml-cpp's own "bad conversion" names neither).
template <typename T>
T valueOf(const YAML::Node& node, const std::string& path, const std::string& key) {
  if (!node.IsDefined()) throw ConfigError(fmt::format("{}: server.{}: is missing", path, key));
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    const std::string written = node.IsScalar()     ? "'" + node.Scalar() + "'"
                                : node.IsSequence() ? "a list"
                                : node.IsMap()      ? "a map"
                                                    : "nothing";
    throw ConfigError(
        fmt::format("{}: server.{}: {} is not {}", path, key, written, expectedKind<T>()));
  }
}

std::string resolve(const fs::path& base, const std::string& p) {
  if (p.empty() || fs::path(p).is_absolute()) return p;
  return (base / p).lexically_normal().string();
}

}  // namespace

protocol::SecurityIdentity securityIdentity(const SecurityOptions& o) {
  protocol::SecurityIdentity id = protocol::identityFromFolder(o.identity);
  if (!o.plugins.empty()) id.plugin_dir = o.plugins;
  return id;
}

std::optional<std::string> checkServerOptions(const ServerOptions& o) {
  if (const std::string problem = protocol::robotIdProblem(o.robot_id); !problem.empty()) {
    return "robot_id: '" + o.robot_id + "' " + problem;
  }
  // RTPS maps a domain to UDP ports 7400 + 250 * id + ...: above 232 they pass 65535.
  if (o.domain_id > kMaxDomainId) {
    return fmt::format(
        "dds.domain_id: {} is not within 0..{} (RTPS maps the domain to UDP port "
        "7400 + 250 x id)",
        o.domain_id, kMaxDomainId);
  }
  // Cyclone's access control cannot parse a governance or permissions document that names a
  // domain above 230: with an identity, such a domain is refused here, not by the plugin.
  if (!o.security.identity.empty() && o.domain_id > kMaxSecureDomainId) {
    return fmt::format(
        "dds.domain_id: {} is above {}, the highest domain DDS Security's governance can name "
        "(Cyclone); with security.identity use 0..{}",
        o.domain_id, kMaxSecureDomainId, kMaxSecureDomainId);
  }
  if (o.robot_id_check_ms < 0 || o.robot_id_check_ms > 60000) {
    return fmt::format("dds.robot_id_check_ms: {} is not within 0..60000", o.robot_id_check_ms);
  }
  const auto& c = o.controller;
  if (c.kind != "simulated" && c.kind != "galil") {
    return "controller.kind: '" + c.kind + "' is not simulated or galil";
  }
  if (c.port <= 0 || c.port > 65535) {
    return fmt::format("controller.port: {} is not a TCP port", c.port);
  }
  if (!(c.speed_steps_s > 0) || !std::isfinite(c.speed_steps_s)) {
    return fmt::format("controller.speed_steps_s: {} must be positive", c.speed_steps_s);
  }
  if (!(c.acceleration_steps_s2 > 0) || !std::isfinite(c.acceleration_steps_s2)) {
    return fmt::format("controller.acceleration_steps_s2: {} must be positive",
                       c.acceleration_steps_s2);
  }
  if (c.timeout_ms < 10 || c.timeout_ms > 60000) {
    return fmt::format("controller.timeout_ms: {} is not within 10..60000", c.timeout_ms);
  }
  if (c.control_period_ms < 1 || c.control_period_ms > 1000) {
    return fmt::format("controller.control_period_ms: {} is not within 1..1000",
                       c.control_period_ms);
  }
  if (o.max_targets < 1 || o.max_targets > workflow::kMaxTargets) {
    return fmt::format("planning.max_targets: {} is not within 1..{}", o.max_targets,
                       workflow::kMaxTargets);
  }
  if (!(o.max_total_rotation_deg > 0) || o.max_total_rotation_deg > 360.0) {
    return fmt::format("planning.max_total_rotation_deg: {} is not within (0, 360]",
                       o.max_total_rotation_deg);
  }
  const auto& g = o.openigtlink;
  if (g.port < 0 || g.port > 65535) {
    return fmt::format("openigtlink.port: {} is not a TCP port (0..65535; 0 = any)", g.port);
  }
  if (!(g.timeout_s >= 0.5) || g.timeout_s > 3600.0) {
    return fmt::format("openigtlink.timeout_s: {} s; must be within 0.5..3600", g.timeout_s);
  }
  if (!(g.tip_rate_hz >= 1.0) || g.tip_rate_hz > 1000.0) {
    return fmt::format("openigtlink.tip_rate_hz: {} Hz; must be within 1..1000", g.tip_rate_hz);
  }
  if (g.max_scan_mb > 16384) {
    return fmt::format("openigtlink.max_scan_mb: {} MiB; must be within 0..16384", g.max_scan_mb);
  }
  if (!igtl::parseRevision(g.protocol)) {
    return fmt::format(
        "openigtlink.protocol: '{}' is not a BRP revision: slicer (the current 3D "
        "Slicer module) or brp2013 (the 2013 revision's reference robots)",
        g.protocol);
  }
  if (!(o.approval_expiry_s > 0) || !std::isfinite(o.approval_expiry_s)) {
    return fmt::format("approval.expiry_s: {} must be positive", o.approval_expiry_s);
  }
  return std::nullopt;
}

ServerOptions loadServerOptions(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw ConfigError(path + ": " + e.what());
  }
  const fs::path base = fs::path(path).parent_path();
  ServerOptions o;
  const YAML::Node s = root["server"];
  if (!s || !s.IsMap()) throw ConfigError(path + ": server: is missing");
  for (const auto& kv : s) {
    const std::string key = kv.first.Scalar();
    if (key != "robot_id" && key != "robot_config" && key != "dds" && key != "session_root" &&
        key != "controller" && key != "approval" && key != "planning" && key != "tissue" &&
        key != "site" && key != "security" && key != "openigtlink") {
      throw ConfigError(path + ": server." + key +
                        ": unknown key; expected robot_id, robot_config, dds, session_root, "
                        "controller, approval, planning, tissue, site, security, openigtlink");
    }
  }
  try {
    if (s["robot_id"]) o.robot_id = valueOf<std::string>(s["robot_id"], path, "robot_id");
    o.robot_config = resolve(base, valueOf<std::string>(s["robot_config"], path, "robot_config"));
    if (s["session_root"])
      o.session_root = resolve(base, valueOf<std::string>(s["session_root"], path, "session_root"));
    if (const YAML::Node d = s["dds"]) {
      for (const auto& kv : d) {
        const std::string key = kv.first.Scalar();
        if (key == "domain_id") {
          // Read wide, so that -1 or 2^32 is named as out of range, not as a bad conversion.
          const auto id = valueOf<long long>(kv.second, path, "dds." + key);
          if (id < 0 || id > kMaxDomainId) {
            throw ConfigError(
                fmt::format("{}: server.dds.domain_id: {} is not within 0..{} (RTPS "
                            "maps the domain to UDP port 7400 + 250 x id)",
                            path, id, kMaxDomainId));
          }
          o.domain_id = static_cast<std::uint32_t>(id);
        } else if (key == "config") {
          // A name ("site-multicast") is a file in the dds folder beside this one.
          const auto value = valueOf<std::string>(kv.second, path, "dds." + key);
          o.dds_config = protocol::isDdsConfigName(value)
                             ? (base / "dds" / (value + ".xml")).lexically_normal().string()
                             : resolve(base, value);
        } else if (key == "interface") {
          o.dds_site.interface = valueOf<std::string>(kv.second, path, "dds." + key);
        } else if (key == "peers") {
          o.dds_site.peers = valueOf<std::vector<std::string>>(kv.second, path, "dds." + key);
        } else if (key == "robot_id_check_ms") {
          o.robot_id_check_ms = valueOf<int>(kv.second, path, "dds." + key);
        } else {
          throw ConfigError(path + ": server.dds." + key +
                            ": unknown key; expected domain_id, config, interface, peers, "
                            "robot_id_check_ms");
        }
      }
    }
    if (const YAML::Node c = s["controller"]) {
      auto& co = o.controller;
      for (const auto& kv : c) {
        const std::string key = kv.first.Scalar();
        if (key == "kind") {
          co.kind = valueOf<std::string>(kv.second, path, "controller." + key);
        } else if (key == "host") {
          co.host = valueOf<std::string>(kv.second, path, "controller." + key);
        } else if (key == "port") {
          co.port = valueOf<int>(kv.second, path, "controller." + key);
        } else if (key == "speed_steps_s") {
          co.speed_steps_s = valueOf<double>(kv.second, path, "controller." + key);
        } else if (key == "acceleration_steps_s2") {
          co.acceleration_steps_s2 = valueOf<double>(kv.second, path, "controller." + key);
        } else if (key == "control_period_ms") {
          co.control_period_ms = valueOf<int>(kv.second, path, "controller." + key);
        } else if (key == "timeout_ms") {
          co.timeout_ms = valueOf<int>(kv.second, path, "controller." + key);
        } else {
          throw ConfigError(path + ": server.controller." + key +
                            ": unknown key; expected kind, host, port, speed_steps_s, "
                            "acceleration_steps_s2, control_period_ms, timeout_ms");
        }
      }
    }
    if (s["site"]) o.site_path = resolve(base, valueOf<std::string>(s["site"], path, "site"));
    if (const YAML::Node t = s["tissue"]) {
      for (const auto& kv : t) {
        const std::string key = kv.first.Scalar();
        if (key == "profiles") {
          o.tissue_profiles = resolve(base, valueOf<std::string>(kv.second, path, "tissue." + key));
        } else if (key == "name") {
          o.tissue_name = valueOf<std::string>(kv.second, path, "tissue." + key);
        } else {
          throw ConfigError(path + ": server.tissue." + key +
                            ": unknown key; expected profiles, name");
        }
      }
    }
    if (const YAML::Node pl = s["planning"]) {
      for (const auto& kv : pl) {
        const std::string key = kv.first.Scalar();
        if (key == "max_targets") {
          o.max_targets = valueOf<std::size_t>(kv.second, path, "planning." + key);
        } else if (key == "max_total_rotation_deg") {
          o.max_total_rotation_deg = valueOf<double>(kv.second, path, "planning." + key);
        } else {
          throw ConfigError(path + ": server.planning." + key +
                            ": unknown key; expected max_targets, max_total_rotation_deg");
        }
      }
    }
    if (const YAML::Node sec = s["security"]) {
      for (const auto& kv : sec) {
        const std::string key = kv.first.Scalar();
        if (key == "identity") {
          const auto folder = valueOf<std::string>(kv.second, path, "security." + key);
          o.security.identity = folder.empty() ? "" : resolve(base, folder);
        } else if (key == "plugins") {
          o.security.plugins = valueOf<std::string>(kv.second, path, "security." + key);
        } else {
          throw ConfigError(path + ": server.security." + key +
                            ": unknown key; expected identity, plugins");
        }
      }
    }
    if (const YAML::Node g = s["openigtlink"]) {
      auto& go = o.openigtlink;
      for (const auto& kv : g) {
        const std::string key = kv.first.Scalar();
        if (key == "enabled") {
          go.enabled = valueOf<bool>(kv.second, path, "openigtlink." + key);
        } else if (key == "address") {
          go.address = valueOf<std::string>(kv.second, path, "openigtlink." + key);
        } else if (key == "port") {
          go.port = valueOf<int>(kv.second, path, "openigtlink." + key);
        } else if (key == "timeout_s") {
          go.timeout_s = valueOf<double>(kv.second, path, "openigtlink." + key);
        } else if (key == "allow_motion_approval") {
          go.allow_motion_approval = valueOf<bool>(kv.second, path, "openigtlink." + key);
        } else if (key == "protocol") {
          go.protocol = valueOf<std::string>(kv.second, path, "openigtlink." + key);
        } else if (key == "tip_rate_hz") {
          go.tip_rate_hz = valueOf<double>(kv.second, path, "openigtlink." + key);
        } else if (key == "max_scan_mb") {
          go.max_scan_mb = valueOf<std::uint64_t>(kv.second, path, "openigtlink." + key);
        } else {
          throw ConfigError(path + ": server.openigtlink." + key +
                            ": unknown key; expected enabled, address, port, timeout_s, "
                            "allow_motion_approval, protocol, tip_rate_hz, max_scan_mb");
        }
      }
    }
    if (const YAML::Node a = s["approval"]) {
      for (const auto& kv : a) {
        const std::string key = kv.first.Scalar();
        if (key == "approvers") {
          o.approvers = valueOf<std::vector<std::string>>(kv.second, path, "approval." + key);
        } else if (key == "expiry_s") {
          o.approval_expiry_s = valueOf<double>(kv.second, path, "approval." + key);
        } else {
          throw ConfigError(path + ": server.approval." + key +
                            ": unknown key; expected approvers, expiry_s");
        }
      }
    }
  } catch (const YAML::Exception& e) {
    throw ConfigError(path + ": server: " + e.what());
  }
  if (auto bad = checkServerOptions(o)) throw ConfigError(path + ": server." + *bad);
  return o;
}

}  // namespace ignav::server
