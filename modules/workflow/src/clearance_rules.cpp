// The whole needle against the patient's avoided structures (issue 41; session_rules.hpp).
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "ignav/anatomy/clearance.hpp"
#include "session_rules.hpp"

namespace ignav::workflow::detail {
namespace {

// Centreline samples: an arc of the stylet's 35 mm radius strays 0.9 µm from its 0.5 mm chords.
constexpr double kCentrelineStep_mm = 0.5;
// The closest approach is searched at this spacing where the needle is near a structure.
constexpr double kSearchStep_mm = 0.1;

// The tissue whose landing spread (from its fit's covariance) the aim carries, if it was fitted
// in this session.
const FittedTissue* fittedAim(const Session& s) {
  if (!s.aim_tissue) return nullptr;
  for (const auto& f : s.fitted_tissues)
    if (f.profile.name == s.aim_tissue->name) return &f;
  return nullptr;
}

}  // namespace

void checkClearance(const Session& s, Target& t) {
  const auto& loaded = s.structures.loaded;
  if (!loaded.set || !s.registration || !t.solution.reachable()) return;
  const auto& kin = s.robot->kinematics;
  const auto& reg = *s.registration;
  const auto& instrument = kin.instrument();
  const kinematics::Joints& joints = t.commandedJoints();
  const auto centreline = kin.centreline(joints, kCentrelineStep_mm);
  anatomy::NeedleBody body(2);
  for (const auto& p : centreline.cannula_mm)
    body[0].centreline_lps_mm.push_back(reg.toImage(p));
  for (const auto& p : centreline.stylet_mm)
    body[1].centreline_lps_mm.push_back(reg.toImage(p));
  // Robot millimetres to image millimetres: the registration's scale.
  body[0].radius_mm = 0.5 * instrument.cannula_outer_diameter_mm / reg.scale;
  body[1].radius_mm = 0.5 * instrument.stylet_outer_diameter_mm / reg.scale;

  // The uncertainty's parts that do not depend on where along the needle.
  const auto& settings = s.robot->config.registration;
  const bool tre_known = !reg.image_mm.empty();
  const auto fiducials = tre_known ? registration::describeFiducials(reg.image_mm)
                                   : registration::FiducialConfiguration{};
  double landing_se_mm = 0.0;
  if (const FittedTissue* fitted = fittedAim(s); fitted && !t.reached) {
    compensation::DeflectionModel model;
    model.needle = fitted->profile.needle;
    model.tissue = fitted->profile.tissue;
    landing_se_mm = landingSe_mm(kin, model, fitted->fit, joints);
    if (!std::isfinite(landing_se_mm)) landing_se_mm = 0.0;  // the aim refuses such poses
  }
  // A deflection the profile predicts and the aim leaves uncompensated shifts the whole path.
  const double drift_mm = !t.compensated && std::isfinite(t.predicted_deviation_mm)
                              ? std::abs(t.predicted_deviation_mm)
                              : 0.0;

  const auto& set = *loaded.set;
  std::string refusal;
  for (std::size_t n = 0; n < set.structures.size(); ++n) {
    const auto& role = s.structures.roles.at(n);
    if (role.role != anatomy::Role::kAvoid) continue;
    const auto& field = *loaded.fields.at(n);
    const auto closest = anatomy::closestApproach(body, field, kSearchStep_mm);
    StructureClearance c;
    c.structure = set.structures[n].name;
    c.distance_mm = closest.distance_mm;
    c.margin_mm = role.margin_mm;
    c.part = closest.piece == 0 ? "cannula" : "stylet";
    c.needle_lps_mm = closest.needle_lps_mm;
    c.structure_lps_mm = closest.structure_lps_mm;
    c.beyond_reach = closest.distance_mm + body[closest.piece].radius_mm >= field.reach_mm();
    // Without fiducials (a matrix given), the TRE the robot config accepts at most.
    const double tre_mm = tre_known ? registration::expectedTre_mm(fiducials, closest.needle_lps_mm,
                                                                   settings.fle_mm, reg.kind)
                                    : settings.max_tre_mm;
    c.uncertainty_mm = anatomy::clearanceUncertainty_mm(tre_mm, landing_se_mm, drift_mm);
    if (c.tooClose() && refusal.empty()) {
      const auto& p = c.needle_lps_mm;
      refusal = fmt::format(
          "too_close: the {} passes {} '{}' ({:.2f} mm surface to surface, less {:.2f} mm "
          "uncertainty, against a margin of {:.1f} mm) at ({:.1f}, {:.1f}, {:.1f}) mm LPS",
          c.part, c.distance_mm < 0.0 ? fmt::format("{:.2f} mm into", -c.distance_mm) : "close to",
          c.structure, c.distance_mm, c.uncertainty_mm, c.margin_mm, p.x(), p.y(), p.z());
    }
    t.clearances.push_back(std::move(c));
  }
  t.clearance_refusal = std::move(refusal);
}

}  // namespace ignav::workflow::detail
