#include "verification_view.hpp"

#include <cstdio>
#include <string>

namespace ignav::ctl {
namespace {

std::string point(const protocol::Point3& p) {
  char text[64];
  std::snprintf(text, sizeof text, "(%7.2f,%7.2f,%7.2f)", p.x, p.y, p.z);
  return text;
}

std::string ids(const std::vector<std::uint32_t>& v, const char* prefix) {
  std::string out;
  for (auto id : v)
    out += (out.empty() ? "" : ", ") + std::string(prefix) + std::to_string(id);
  return out;
}

}  // namespace

void printVerification(const protocol::StateMirror& state) {
  if (!state.verification || state.verification->status == "none") {
    std::printf("no confirmation CT measured (load_confirmation PATH after motion)\n");
    if (state.verification && !state.verification->message.empty())
      std::printf("%s\n", state.verification->message.c_str());
    return;
  }
  const protocol::VerificationState& v = *state.verification;
  std::printf("confirmation CT %s: %s\n%s\n", v.source.c_str(), v.status.c_str(),
              v.message.c_str());
  if (!v.detection_summary.empty()) std::printf("%s\n", v.detection_summary.c_str());
  if (!v.targets.empty()) {
    std::printf("\n%-4s %-6s %-26s %-26s %7s %7s %7s %9s  %s\n", "id", "seed", "planned (robot mm)",
                "actual (robot mm)", "error", "lateral", "depth", "predicted", "matched");
    for (const auto& t : v.targets) {
      char predicted[16] = "-";
      if (t.predicted_robot)
        std::snprintf(predicted, sizeof predicted, "%.2f", t.predicted_error_mm);
      std::printf("T%-3u #%-5u %-26s %-26s %7.2f %7.2f %7.2f %9s  %s\n", t.target_id, t.seed_id,
                  point(t.planned_robot).c_str(), point(t.actual_robot).c_str(), t.error_mm,
                  t.lateral_mm, t.depth_mm, predicted, t.matched.c_str());
    }
    std::printf("\n%s\n", v.summary.c_str());
    std::printf("lateral %.2f ± %.2f mm, depth %+.2f ± %.2f mm (signed, + deeper)\n",
                v.lateral.mean_mm, v.lateral.sd_mm, v.depth.mean_mm, v.depth.sd_mm);
  }
  if (!v.missing_targets.empty())
    std::printf("no seed found for %s\n", ids(v.missing_targets, "T").c_str());
  if (!v.extra_seeds.empty())
    std::printf("seeds of no target: %s\n", ids(v.extra_seeds, "#").c_str());
  for (const auto& f : v.fitted_tissues) {
    std::printf(
        "tissue '%s' fitted to %u targets: λ1 %.3f ± %.3f, λ2 %.3f ± %.3f; RMS %.3f mm (plain "
        "bicycle %.3f, no deflection %.3f)%s%s\n",
        f.name.c_str(), f.targets, f.lambda1, f.lambda1_se, f.lambda2, f.lambda2_se, f.rms_mm,
        f.rms_bicycle_mm, f.rms_no_deflection_mm, f.limit.empty() ? "" : "; ", f.limit.c_str());
  }
  if (!v.aim_tissue.empty()) std::printf("aiming for tissue '%s'\n", v.aim_tissue.c_str());
}

}  // namespace ignav::ctl
