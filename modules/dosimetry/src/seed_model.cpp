// A seed model's published TG-43U1 data from its file, checked (tg43.hpp).
#include <cmath>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "ignav/dosimetry/tg43.hpp"

namespace ignav::dosimetry {
namespace {

Error bad(const std::string& what) {
  return makeError(ErrorCode::kConfig, what, "bad_seed_model");
}

// A table's distances (or angles): at least `least`, finite, increasing, within [lo, hi].
std::string checkAxis(const std::vector<double>& xs, const std::string& field, std::size_t least,
                      double lo, double hi) {
  if (xs.size() < least) return fmt::format("{} needs at least {} values", field, least);
  for (std::size_t i = 0; i < xs.size(); ++i) {
    if (!std::isfinite(xs[i]) || xs[i] < lo || xs[i] > hi)
      return fmt::format("{}[{}] = {} is outside {:g}-{:g}", field, i, xs[i], lo, hi);
    if (i > 0 && xs[i] <= xs[i - 1])
      return fmt::format("{} must increase ({} after {})", field, xs[i], xs[i - 1]);
  }
  return "";
}

std::string checkValues(const std::vector<double>& ys, std::size_t n, const std::string& field,
                        bool positive) {
  if (ys.size() != n)
    return fmt::format("{} holds {} values for {} distances", field, ys.size(), n);
  for (std::size_t i = 0; i < ys.size(); ++i) {
    if (!std::isfinite(ys[i]) || ys[i] < 0.0 || (positive && ys[i] == 0.0))
      return fmt::format("{}[{}] = {} is not a {} number", field, i, ys[i],
                         positive ? "positive" : "non-negative");
  }
  return "";
}

std::vector<double> numbers(const YAML::Node& node, const std::string& field) {
  if (!node) throw std::runtime_error(field + " is missing");
  return node.as<std::vector<double>>();
}

double number(const YAML::Node& node, const std::string& field) {
  if (!node) throw std::runtime_error(field + " is missing");
  return node.as<double>();
}

// The first thing wrong with a model, or "".
std::string problem(const SeedModel& m) {
  if (m.name.empty()) return "name is empty";
  const double lambda = m.dose_rate_constant_cGy_per_h_per_U;
  if (!std::isfinite(lambda) || lambda <= 0.0 || lambda > 2.0)
    return fmt::format("dose_rate_constant_cGy_per_h_per_U = {} is outside 0-2", lambda);
  if (!std::isfinite(m.active_length_cm) || m.active_length_cm <= 0.0 || m.active_length_cm > 1.0)
    return fmt::format("active_length_cm = {} is outside 0-1 cm", m.active_length_cm);
  if (!std::isfinite(m.half_life_h) || m.half_life_h <= 0.0)
    return fmt::format("half_life_days = {} is not a positive number", m.half_life_h / 24.0);
  for (const std::string& why :
       {checkAxis(m.radial_r_cm, "radial_dose.r_cm", 2, 1e-3, 20.0),
        checkValues(m.radial_g, m.radial_r_cm.size(), "radial_dose.g_L", true),
        checkAxis(m.anisotropy_r_cm, "anisotropy.r_cm", 1, 1e-3, 20.0),
        checkAxis(m.anisotropy_theta_deg, "anisotropy.theta_deg", 2, 0.0, 90.0)}) {
    if (!why.empty()) return why;
  }
  if (m.anisotropy_theta_deg.front() != 0.0 || m.anisotropy_theta_deg.back() != 90.0)
    return "anisotropy.theta_deg must run from 0 to 90";
  if (m.anisotropy_f.size() != m.anisotropy_theta_deg.size())
    return fmt::format("anisotropy.F holds {} rows for {} angles", m.anisotropy_f.size(),
                       m.anisotropy_theta_deg.size());
  for (std::size_t k = 0; k < m.anisotropy_f.size(); ++k) {
    const auto field = fmt::format("anisotropy.F[{}] ({:g}°)", k, m.anisotropy_theta_deg[k]);
    if (auto why = checkValues(m.anisotropy_f[k], m.anisotropy_r_cm.size(), field, false);
        !why.empty())
      return why;
  }
  if (m.phi_an_r_cm.empty() && m.phi_an.empty()) return "";  // φ_an is optional
  if (auto why = checkAxis(m.phi_an_r_cm, "anisotropy_factor.r_cm", 1, 1e-3, 20.0); !why.empty())
    return why;
  return checkValues(m.phi_an, m.phi_an_r_cm.size(), "anisotropy_factor.phi_an", true);
}

}  // namespace

Status validate(const SeedModel& m) {
  const std::string why = problem(m);
  if (why.empty()) return Ok{};
  return bad(why);
}

Expected<SeedModel> readSeedModel(const std::string& path) {
  SeedModel m;
  try {
    const YAML::Node root = YAML::LoadFile(path);
    m.name = root["name"] ? root["name"].as<std::string>() : "";
    m.isotope = root["isotope"] ? root["isotope"].as<std::string>() : "";
    m.citation = root["citation"] ? root["citation"].as<std::string>() : "";
    m.dose_rate_constant_cGy_per_h_per_U =
        number(root["dose_rate_constant_cGy_per_h_per_U"], "dose_rate_constant_cGy_per_h_per_U");
    m.active_length_cm = number(root["active_length_cm"], "active_length_cm");
    m.half_life_h = 24.0 * number(root["half_life_days"], "half_life_days");
    const YAML::Node radial = root["radial_dose"];
    m.radial_r_cm = numbers(radial["r_cm"], "radial_dose.r_cm");
    m.radial_g = numbers(radial["g_L"], "radial_dose.g_L");
    const YAML::Node f = root["anisotropy"];
    m.anisotropy_r_cm = numbers(f["r_cm"], "anisotropy.r_cm");
    m.anisotropy_theta_deg = numbers(f["theta_deg"], "anisotropy.theta_deg");
    if (!f["F"]) throw std::runtime_error("anisotropy.F is missing");
    m.anisotropy_f = f["F"].as<std::vector<std::vector<double>>>();
    if (const YAML::Node phi = root["anisotropy_factor"]) {
      m.phi_an_r_cm = numbers(phi["r_cm"], "anisotropy_factor.r_cm");
      m.phi_an = numbers(phi["phi_an"], "anisotropy_factor.phi_an");
    }
  } catch (const std::exception& e) {  // YAML's and ours: the file or field named
    return bad(path + ": " + e.what());
  }
  if (m.isotope.empty()) return bad(path + ": isotope is missing");
  if (m.citation.empty())
    return bad(path + ": citation is missing (where the numbers are published)");
  if (auto ok = validate(m); !ok.ok()) return bad(path + ": " + ok.error().message);
  return m;
}

}  // namespace ignav::dosimetry
