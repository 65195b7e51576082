#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <ctime>

#include "ignav/verification/targeting_report.hpp"
#include "ignav/workflow/reducer.hpp"

namespace ignav::workflow {
namespace {

std::string utc(double unix_s) {
  const auto t = static_cast<std::time_t>(unix_s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%H:%M:%S", &tm);
  return buf;
}

// The robot and every approved motion: who approved it, when, how long it took, how it ended.
std::string motionSection(const Session& s) {
  std::string out = "\n## Robot\n\n";
  out += fmt::format("- motors at {} / {} / {} steps (last verified)\n", s.position.motor[0],
                     s.position.motor[1], s.position.motor[2]);
  if (s.pending) out += "- waiting for approval: " + s.pending->summary + "\n";
  if (!s.fault.empty()) out += "- fault: " + s.fault + "\n";
  if (s.motions.empty()) return out + "\nNo motion approved yet.\n";
  out +=
      "\n| plan | target | approved by | at (UTC) | took (s) | outcome |\n"
      "|---|---|---|---|---|---|\n";
  for (const auto& m : s.motions) {
    out +=
        fmt::format("| {} | {} | {} | {} | {} | {} |\n", m.plan_id,
                    m.target_id == 0 ? std::string("retract") : "T" + std::to_string(m.target_id),
                    m.approved_by, utc(m.approved_s),
                    m.ended_s >= 0 ? fmt::format("{:.2f}", m.ended_s - m.approved_s) : "—",
                    m.ended_s >= 0 ? m.outcome : "under way");
  }
  return out;
}

// The confirmation CT's targeting errors (issue 23): the paper's Table V for this session, with
// what the model had predicted, the figure (the reports thread writes it), the fitted tissues.
std::string verificationSection(const Session& s) {
  const Confirmation& c = s.confirmation;
  std::string out;
  if (c.status != "none" || c.measuring != 0) {
    out += "\n## Targeting error (confirmation CT)\n\n";
    out += fmt::format("- confirmation CT: {} ({})\n- {}\n", c.source.empty() ? "—" : c.source,
                       c.status, c.message);
    if (c.measuring != 0) out += "- measuring " + c.measuring_source + "\n";
  }
  if (c.summary && !c.targets.empty()) {
    std::vector<verification::TargetError> errors;
    std::map<std::uint32_t, double> predicted;
    for (const auto& m : c.targets) {
      errors.push_back(m.error);
      if (std::isfinite(m.predicted_error_mm)) predicted[m.error.target_id] = m.predicted_error_mm;
    }
    out +=
        "\n" + verification::targetingTableMarkdown(
                   errors, *c.summary, predicted.empty() ? std::nullopt : std::optional(predicted));
    out +=
        "\n\"predicted\" is the model's landing error for the joints used: the tissue a target "
        "was aimed for (use_tissue), else the session's tissue.\n";
    out += "\n![planned vs actual in the feasible volume](verification/targeting.png)\n";
  }
  if (!s.fitted_tissues.empty()) {
    out += "\n### Tissues fitted from the errors\n\n";
    for (const auto& f : s.fitted_tissues) {
      const auto& se = f.fit.standard_errors;
      out += fmt::format(
          "- **{}** from {} targets: λ1 {:.3f} ± {:.3f}, λ2 {:.3f} ± {:.3f}; RMS {:.3f} mm "
          "(plain bicycle {:.3f}, no deflection {:.3f}){}\n",
          f.profile.name, f.targets, f.fit.tissue.lambda1, se.size() > 0 ? se[0] : 0.0,
          f.fit.tissue.lambda2, se.size() > 1 ? se[1] : 0.0, f.fit.rms_mm, f.fit.rms_bicycle_mm,
          f.fit.rms_no_deflection_mm, f.fit.limit.empty() ? "" : "; " + f.fit.limit);
    }
    out += "\nAs a configs/tissues.yaml: `tissues_fitted.yaml` in this folder.\n";
  }
  if (s.aim_tissue) {
    out +=
        fmt::format("\nThe plan aims for tissue '{}' (compensated joints).\n", s.aim_tissue->name);
  }
  return out;
}

// The patient's structures (issue 41) and every target's whole-needle clearance from the avoided
// ones, with the overrides operators gave.
std::string anatomySection(const Session& s) {
  const auto& st = s.structures;
  if (st.status == "none") return "";
  std::string out = fmt::format("\n## Structures ({})\n\n- {} {}: {}\n", st.source, st.status,
                                s.site ? "(site: " + s.site->name + ")" : "", st.message);
  if (!st.loaded.set) return out;
  out +=
      "- for 3D Slicer: `structures.seg.nrrd` in this folder, the structures as the plan used "
      "them (their roles and margins as segment tags)\n";
  out +=
      "\n| target | structure | clearance (mm) | at | margin (mm) | uncertainty (mm) | verdict "
      "|\n|---|---|---|---|---|---|---|\n";
  for (const auto& t : s.targets) {
    for (const auto& c : t.clearances) {
      out += fmt::format(
          "| T{} | {} | {}{:.2f} | {} ({:.1f}, {:.1f}, {:.1f}) | {:g} | {:.2f} | {} |\n", t.id,
          c.structure, c.beyond_reach ? "> " : "", c.distance_mm, c.part, c.needle_lps_mm.x(),
          c.needle_lps_mm.y(), c.needle_lps_mm.z(), c.margin_mm, c.uncertainty_mm,
          !c.tooClose()                  ? "clear"
          : t.clearance_override.empty() ? "**too close**"
                                         : "too close, overridden: " + t.clearance_override);
    }
  }
  out +=
      "\nClearance: from the needle's surface (the cannula's, then the stylet's outer diameter) "
      "to the structure's, at the closest point of its whole length; negative inside. "
      "Uncertainty: 2 SD of the expected registration error there (and of the aimed tissue's "
      "landing), plus any deflection the aim leaves uncompensated.\n";
  return out;
}

// The seeds' dose (compute_dose): the metrics planned and delivered side by side, the DVH plot,
// the files for 3D Slicer and planning systems.
std::string doseSection(const Session& s) {
  const auto& d = s.dose;
  if (d.status == "none") return "";
  std::string out = fmt::format("\n## Dose ({})\n\n- {}\n", d.status, d.message);
  const auto& computed = d.computed;
  if (!computed) return out;
  const double rx = computed->seeds.prescription_Gy;
  out += fmt::format("\n| dose | seeds | {} V100 | D90 | V150 |", computed->structure);
  const auto& first = computed->doses.front().evaluation;
  for (const auto& o : first.organs)
    out += fmt::format(" {} D10 | D2cc |", o.name);
  out += "\n|---|---|---|---|---|";
  for (std::size_t n = 0; n < first.organs.size(); ++n)
    out += "---|---|";
  out += "\n";
  for (const auto& dose : computed->doses) {
    const auto& e = dose.evaluation;
    out += fmt::format("| {} | {} | {:.1f} % | {:.1f} % ({:.0f} Gy) | {:.1f} % |", dose.what,
                       dose.seeds, 100.0 * e.target.v100, e.target.d90_percent,
                       e.target.d90_percent * rx / 100.0, 100.0 * e.target.v150);
    for (const auto& o : e.organs)
      out += fmt::format(" {:.1f} % | {:.1f} Gy |", o.metrics.d10_percent, o.metrics.d2cc_Gy);
    out += "\n";
  }
  out += fmt::format(
      "\nTG-43U1 ({} at {:g} U, {:g} Gy prescribed), judged on every voxel of the structures; "
      "the percentages are of the prescription.\n",
      computed->seeds.seed_model, computed->seeds.strength_U, rx);
  const auto& files = computed->files;
  if (std::find(files.begin(), files.end(), "dose/dvh.png") != files.end())
    out += "\n![dose-volume histograms](dose/dvh.png)\n";
  if (!files.empty()) {
    out +=
        "\nFor 3D Slicer (SlicerRT) and planning systems, in `dose/`: the structures "
        "(`structures_rtstruct.dcm`), the seeds as RT Plans (`*_rtplan.dcm`), each dose as RT "
        "Dose (`*_rtdose.dcm`) and NRRD (`*_dose.nrrd`, Gy), the DVHs as `dvh.csv`.\n";
  }
  return out;
}

// Where the robot was proposed to stand (place_robot) and, once mounted, where it stands.
std::string placementSection(const Session& s) {
  const auto& p = s.robot_placement;
  if (p.status == "none") return "";
  std::string out = fmt::format("\n## Robot placement ('{}' from {})\n\n- {}: {}\n", p.structure,
                                p.limits.approach, p.status, p.message);
  if (!p.poses.empty()) {
    out +=
        "- for 3D Slicer: `robot_placement.tfm` (the best pose; put `feasible_volume.ply`, in "
        "the robot's frame, under it), `robot_placement.mrk.json` (the entry points)\n";
    out +=
        "\n| pose | coverage | entry (mm LPS) | axis (LPS) | tilt | shift | origin outside the "
        "skin |\n|---|---|---|---|---|---|---|\n";
    for (std::size_t n = 0; n < p.poses.size(); ++n) {
      const auto& q = p.poses[n];
      const auto& e = q.skin.entry_lps_mm;
      const Eigen::Vector3d a = q.pose.insertion();
      out += fmt::format(
          "| {} | {:.1f} % | ({:.1f}, {:.1f}, {:.1f}) | ({:.3f}, {:.3f}, {:.3f}) | {:.1f}° | "
          "{:.1f} mm | {:.1f} mm{} |\n",
          n == 0 ? "proposed" : "alternative " + std::to_string(n), 100.0 * q.coverage.fraction(),
          e.x(), e.y(), e.z(), a.x(), a.y(), a.z(), q.tilt_deg, q.shift_mm, q.skin.skin_distance_mm,
          q.skin.seen ? "" : " (no skin on the CT)");
    }
  }
  if (!p.mounted_message.empty()) out += "\n- mounted: " + p.mounted_message + "\n";
  return out;
}

}  // namespace

std::string procedureReport(const Session& s, const std::vector<std::string>& images) {
  std::string out = fmt::format("# Session {}\n\n", s.session_id);
  out += fmt::format("- phase: **{}** (revision {}, {} commands accepted, {} rejected)\n",
                     toString(s.phase), s.revision, s.accepted, s.rejected);
  if (s.robot) {
    out += fmt::format("- robot: {} (`{}`)\n", s.robot->config.name, s.robot_path);
  }
  if (s.tissue) {
    out += fmt::format(
        "- tissue: {} (λ1 {:g}, λ2 {:g}; {}). \"drift\" below is a model prediction (extended "
        "bicycle model): the cannula tip's sideways deviation after its zc of insertion\n",
        s.tissue->name, s.tissue->tissue.lambda1, s.tissue->tissue.lambda2, s.tissue->source);
  }
  out += fmt::format("- CT: {} {}\n", s.volume_status.status,
                     s.volume_status.message.empty() ? "" : "— " + s.volume_status.message);
  if (s.registration) {
    const auto& r = *s.registration;
    out += fmt::format(
        "- registration: {} from {} points{}, FRE {:.3f} mm, scale {:.5f} "
        "(`image_to_robot.tfm`, `fiducials.mrk.json`)\n",
        registration::toString(r.kind), r.image_mm.size(),
        s.registration_status.auto_detected ? " detected on the CT" : "", r.fre_mm, r.scale);
  } else {
    out += "- registration: none\n";
  }
  out += "\n## Targets (`targets.mrk.json`)\n\n";
  if (s.targets.empty())
    return out + "None.\n" + anatomySection(s) + placementSection(s) + motionSection(s);
  // (no slices without targets)
  out +=
      "| # | id | status | LPS (mm) | robot (mm) | θc (°) | zc (mm) | zs (mm) | steps | TRE (mm) "
      "| drift (mm, model) | reached (UTC) |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (std::size_t i = 0; i < s.targets.size(); ++i) {
    const auto& t = s.targets[i];
    const auto& j = t.commandedJoints();
    const bool planned = t.plannable();
    out += fmt::format(
        "| {} | T{} | {} | ({:.2f}, {:.2f}, {:.2f}) | {} | {} | {} | {} | {} | {} | {} | {} |\n",
        i + 1, t.id, t.status(), t.lps_mm.x(), t.lps_mm.y(), t.lps_mm.z(),
        t.registered ? fmt::format("({:.2f}, {:.2f}, {:.2f})", t.robot_mm.x(), t.robot_mm.y(),
                                   t.robot_mm.z())
                     : "—",
        planned ? fmt::format("{:.2f}", j.theta_c_rad * 180.0 / M_PI) : "—",
        planned ? fmt::format("{:.3f}", j.z_c_mm) : "—",
        planned ? fmt::format("{:.3f}", j.z_s_mm) : "—",
        planned ? fmt::format("{} / {} / {}", t.steps.motor[0], t.steps.motor[1], t.steps.motor[2])
                : "—",
        !t.registered          ? "—"
        : std::isnan(t.tre_mm) ? "unknown (matrix)"
                               : fmt::format("{:.2f}{}", t.tre_mm, t.tre_warning ? " ⚠" : ""),
        std::isfinite(t.predicted_deviation_mm) ? fmt::format("{:.2f}", t.predicted_deviation_mm)
                                                : "—",
        t.reached ? utc(t.reached_s) : "—");
  }
  std::string notes;
  for (const auto& t : s.targets) {
    if (!t.plannable() || t.outside_volume || !t.path_warning.empty())
      notes += "- T" + std::to_string(t.id) + ": " + t.message + "\n";
  }
  if (!notes.empty()) out += "\n" + notes;
  out += anatomySection(s);
  out += doseSection(s);
  out += placementSection(s);
  out += motionSection(s);
  out += verificationSection(s);
  if (!images.empty()) {
    out +=
        "\n## Slices\n\nThrough each target: the feasible region (green), the targets, the "
        "fiducials, the planned needle path (cyan) and, once reached, the tip where the "
        "verified steps put it (magenta).\n\n";
    for (const auto& image : images)
      out += "![" + image + "](" + image + ")\n";
  }
  return out;
}

}  // namespace ignav::workflow
