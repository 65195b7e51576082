#include "printers.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <vector>

namespace ignav::ctl {
namespace {

using nlohmann::json;
using protocol::Point3;

std::string fmt3(const Point3& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%7.2f, %7.2f, %7.2f)", p.x, p.y, p.z);
  return buf;
}

template <typename T, std::size_t N>
std::string list(const std::array<T, N>& values) {
  return json(values).dump();
}

}  // namespace

void printReply(const protocol::Reply& r, bool as_json, double round_trip_ms) {
  if (as_json) {
    json out = r;  // its JSON view, from the Reply's one list of fields
    if (round_trip_ms >= 0) out["round_trip_ms"] = round_trip_ms;
    std::cout << out.dump() << "\n";
  } else if (r.accepted) {
    std::cout << "accepted" << (r.target_id ? " (target " + std::to_string(r.target_id) + ")" : "")
              << ": " << r.message << "\n";
  } else {
    std::cout << "REJECTED [" << r.error_code << "]: " << r.message << "\n";
  }
}

void printTargets(const protocol::StateMirror& state) {
  std::printf("%-4s %-5s %-26s %-26s %-12s %8s %8s %8s %6s\n", "id", "order", "LPS (mm)",
              "robot (mm)", "status", "θc(deg)", "zc(mm)", "zs(mm)", "TRE");
  std::vector<const protocol::TargetState*> rows;
  for (const auto& [id, t] : state.targets)
    rows.push_back(&t);
  std::sort(rows.begin(), rows.end(),
            [](const protocol::TargetState* a, const protocol::TargetState* b) {
              return a->order < b->order;
            });
  for (const protocol::TargetState* t : rows) {
    std::printf("%-4u %-5u %-26s %-26s %-12s %8.2f %8.3f %8.3f %6.2f\n", t->id, t->order,
                fmt3(t->lps).c_str(), fmt3(t->robot).c_str(), t->status.c_str(),
                t->joints[0] * 180.0 / M_PI, t->joints[1], t->joints[2], t->tre_mm);
    if (t->status != "planned" || !t->path_warning.empty())
      std::printf("     %s\n", t->message.c_str());
    for (const auto& c : t->clearances) {
      std::printf("     %-12s %s%6.2f mm at the %-7s margin %.1f mm, uncertainty %.2f mm%s\n",
                  c.structure.c_str(), c.beyond_reach ? ">" : " ", c.distance_mm, c.part.c_str(),
                  c.margin_mm, c.uncertainty_mm, c.too_close ? "  TOO CLOSE" : "");
    }
    if (!t->clearance_override.empty())
      std::printf("     clearance overridden: %s\n", t->clearance_override.c_str());
  }
}

void printStructures(const protocol::StateMirror& state) {
  if (!state.structures || state.structures->status == "none") {
    std::cout << "no structures are loaded (structures load PATH)\n";
    return;
  }
  const protocol::StructuresState& s = *state.structures;
  std::cout << "structures " << s.status << " (" << s.source << ")"
            << (s.site.empty() ? "" : "; site: " + s.site) << ": " << s.message << "\n";
  for (const auto& x : s.structures) {
    const std::string margin = x.role == "avoid" ? fmt::format("{:g} mm", x.margin_mm) : "";
    std::printf("  %-14s %-7s %7s %10llu voxels %8.2f cm³\n", x.name.c_str(), x.role.c_str(),
                margin.c_str(), static_cast<unsigned long long>(x.voxels), x.volume_cm3);
  }
  if (!s.proposal_status.empty() && s.proposal_status != "none") {
    std::cout << "targets " << s.proposal_status << ": " << s.proposal_message << "\n";
    for (const auto& p : s.proposed)
      std::printf("  P%-4u (%8.2f, %8.2f, %8.2f) mm LPS\n", p.id, p.lps[0], p.lps[1], p.lps[2]);
    if (!s.proposed.empty()) std::cout << "  (targets accept [ID...] makes them targets)\n";
  }
  if (!s.dose_status.empty() && s.dose_status != "none") {
    std::cout << "dose " << s.dose_status << ": " << s.dose_message << "\n";
    for (const auto& d : s.dose) {
      if (std::isfinite(d.d90_percent)) {
        std::printf("  %-14s %-9s V100 %5.1f %%  D90 %5.1f %%  V150 %5.1f %%\n",
                    d.structure.c_str(), d.which.c_str(), 100.0 * d.v100, d.d90_percent,
                    100.0 * d.v150);
      } else {
        std::printf("  %-14s %-9s D10 %5.1f %%  Dmax %6.0f %%  D2cc %6.1f Gy\n",
                    d.structure.c_str(), d.which.c_str(), d.d10_percent, d.dmax_percent, d.d2cc_gy);
      }
    }
  }
  if (s.placement_status.empty() || s.placement_status == "none") return;
  std::cout << "robot placement " << s.placement_status << ": " << s.placement_message << "\n";
  for (std::size_t n = 0; n < s.placements.size(); ++n) {
    const auto& p = s.placements[n];
    std::printf(
        "  %-13s %5.1f %%  entry (%7.1f, %7.1f, %7.1f) mm LPS  axis (%6.3f, %6.3f, %6.3f)  "
        "tilt %4.1f°  %5.1f mm outside the skin\n",
        n == 0 ? "proposed" : fmt::format("alternative {}", n).c_str(), 100.0 * p.coverage,
        p.entry_lps[0], p.entry_lps[1], p.entry_lps[2], p.axis_lps[0], p.axis_lps[1], p.axis_lps[2],
        p.tilt_deg, p.skin_distance_mm);
  }
  if (!s.mounted_message.empty()) std::cout << "  mounted: " << s.mounted_message << "\n";
}

void printApproval(const protocol::StateMirror& s) {
  if (!s.approval || s.approval->status != "pending") {
    std::cout << "no motion is waiting for approval\n";
    return;
  }
  const protocol::ApprovalState& a = *s.approval;
  std::cout << a.summary << "\n"
            << "  plan " << a.plan_id << ", digest " << a.digest << "\n"
            << "  from steps " << list(a.from_steps) << ", expires in "
            << static_cast<int>(a.expires_in_s) << " s; approvers " << json(a.approvers).dump()
            << "\n";
  for (const auto& m : a.moves)
    std::printf("  %-18s %s  %.2f s\n", m.kind.c_str(), list(m.steps).c_str(), m.duration_s);
}

void printMotion(const protocol::StateMirror& s) {
  if (!s.motion) {
    std::cout << "no motion state yet\n";
    return;
  }
  const protocol::MotionState& m = *s.motion;
  std::cout << "controller " << m.controller << ": " << m.state << " (link " << m.lifecycle << ")\n"
            << "  steps " << list(m.steps) << " (verified " << list(m.verified_steps) << ")\n"
            << "  joints θc " << m.joints[0] * 180.0 / M_PI << "°, zc " << m.joints[1] << " mm, zs "
            << m.joints[2] << " mm\n"
            << "  tip robot " << fmt3(m.tip_robot)
            << (m.tip_lps ? ", LPS " + fmt3(*m.tip_lps) : std::string()) << "\n";
  if (m.plan_id != 0) {
    std::cout << "  plan " << m.plan_id << " to target " << m.target_id << ": move " << m.move_index
              << " of " << m.move_count << " (" << m.move_kind << ") towards " << list(m.goal_steps)
              << "\n";
  }
  if (!m.fault.empty()) std::cout << "  fault: " << m.fault << "\n";
}

void printStatus(const protocol::StateMirror& s) {
  using protocol::RegistrationState;
  using protocol::VolumeState;
  using protocol::WorkflowState;
  const auto or_dash = [](const auto& part, auto field) {
    return part ? json((*part).*field).dump() : std::string("-");
  };
  std::cout << "session      " << or_dash(s.health, &protocol::Health::session_dir) << "\n"
            << "phase        " << or_dash(s.workflow, &WorkflowState::phase) << " (revision "
            << or_dash(s.workflow, &WorkflowState::revision) << ")\n"
            << "allowed      " << or_dash(s.workflow, &WorkflowState::allowed_commands) << "\n"
            << "robot        " << or_dash(s.robot, &protocol::RobotState::name) << "\n"
            << "volume       " << or_dash(s.volume, &VolumeState::status) << " "
            << or_dash(s.volume, &VolumeState::message) << "\n"
            << "registration " << or_dash(s.registration, &RegistrationState::status) << " "
            << or_dash(s.registration, &RegistrationState::message) << "\n"
            << "targets      " << s.targets.size() << "\n";
  if (s.workflow && !s.workflow->safety_notice.empty())
    std::cout << "SAFETY       " << s.workflow->safety_notice << "\n";
}

}  // namespace ignav::ctl
