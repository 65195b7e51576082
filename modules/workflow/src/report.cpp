#include <fmt/format.h>

#include <cmath>

#include "ignav/workflow/reducer.hpp"

namespace ignav::workflow {

std::string procedureReport(const Session& s) {
  std::string out = fmt::format("# Session {}\n\n", s.session_id);
  out += fmt::format("- phase: **{}** (revision {}, {} commands accepted, {} rejected)\n",
                     toString(s.phase), s.revision, s.accepted, s.rejected);
  if (s.robot) {
    out += fmt::format("- robot: {} (`{}`)\n", s.robot->config.name, s.robot_path);
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
  if (s.targets.empty()) return out + "None.\n";
  out +=
      "| # | id | status | LPS (mm) | robot (mm) | θc (°) | zc (mm) | zs (mm) | steps | TRE (mm) "
      "|\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (std::size_t i = 0; i < s.targets.size(); ++i) {
    const auto& t = s.targets[i];
    const auto& j = t.solution.joints;
    const bool planned = t.status() == "planned";
    out += fmt::format(
        "| {} | T{} | {} | ({:.2f}, {:.2f}, {:.2f}) | {} | {} | {} | {} | {} | {} |\n", i + 1, t.id,
        t.status(), t.lps_mm.x(), t.lps_mm.y(), t.lps_mm.z(),
        t.registered ? fmt::format("({:.2f}, {:.2f}, {:.2f})", t.robot_mm.x(), t.robot_mm.y(),
                                   t.robot_mm.z())
                     : "—",
        planned ? fmt::format("{:.2f}", j.theta_c_rad * 180.0 / M_PI) : "—",
        planned ? fmt::format("{:.3f}", j.z_c_mm) : "—",
        planned ? fmt::format("{:.3f}", j.z_s_mm) : "—",
        planned ? fmt::format("{} / {} / {}", t.steps.motor[0], t.steps.motor[1], t.steps.motor[2])
                : "—",
        t.registered ? fmt::format("{:.2f}{}", t.tre_mm, t.tre_warning ? " ⚠" : "") : "—");
  }
  std::string notes;
  for (const auto& t : s.targets) {
    if (t.status() != "planned") notes += "- T" + std::to_string(t.id) + ": " + t.message + "\n";
  }
  if (!notes.empty()) out += "\n" + notes;
  return out;
}

}  // namespace ignav::workflow
