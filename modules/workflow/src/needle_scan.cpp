// scan_needle's job (issue 40, re-planning during an insertion): the intermittent CT measured as a
// confirmation CT is (markers, seeds, needles with their centrelines), registered, the paused
// needle's tip chosen, the tissue refitted with its path, the rest of the insertion re-aimed from
// that path (compensation::reaimFromPath) and the targets after it aimed for the refitted tissue.
// Pure but slow (I/O, a threshold scan, a fit with a path): the server runs it on its job thread;
// the reducer gets needle_scanned with the proposal, or needle_scan_failed with why.
#include <fmt/format.h>
#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <optional>

#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/reducer.hpp"
#include "motion.hpp"
#include "session_rules.hpp"

namespace ignav::workflow {
namespace {

using detail::jointsText;
using detail::landingSe_mm;

// A needle tip on the scan farther than this from where the model puts the paused one's is
// another needle (or none of this insertion): the scan is refused rather than re-aimed from it.
constexpr double kTipSearch_mm = 10.0;

// A refitted tissue aims a pose only where it determines the landing there: the landing's
// standard error from the fit's covariance at most this. One needle's path seldom determines two
// slip parameters (λ1 ± 2 to ± 100 on the phantom), and aiming with such a fit turned a 0.12 mm
// mean into 0.51 mm over 20 targets (docs/VERIFICATION.md); the aim's model, corrected by the
// path, is used instead.
constexpr double kMaxLandingSe_mm = 0.2;

// What the plan aims with: the aim's tissue, or none (a model that does not deflect: the needle's
// own curvature 0 and no slip, so its path is the kinematics').
compensation::DeflectionModel aimModel(const NeedleScanJob& job) {
  compensation::DeflectionModel model;
  if (job.aim_tissue) {
    model.needle = job.aim_tissue->needle;
    model.tissue = job.aim_tissue->tissue;
  } else {
    if (job.tissue) model.needle = job.tissue->needle;
    model.needle.curvature_per_mm = 0.0;
    model.tissue = {};
  }
  return model;
}

Input failed(const NeedleScanJob& job, const std::string& why) {
  Input in;
  in.kind = InputKind::kNeedleScanFailed;
  in.job = job.scan.job;
  in.path = job.scan.source;
  in.error = why;
  return in;
}

}  // namespace

std::optional<NeedleScanJob> pendingNeedleScan(const Session& s) {
  if (s.scanning_needle == 0 || !s.robot) return std::nullopt;
  NeedleScanJob job;
  job.scan = {s.scanning_needle, s.scanning_source, s.robot, s.scanning_matrix};
  job.session_registration = s.registration;
  job.aim_tissue = s.aim_tissue;
  job.tissue = s.tissue;
  job.records = detail::measuredRecords(s);
  const Target* paused = detail::pausedInsertion(s);
  if (!paused) return std::nullopt;
  job.target_id = paused->id;
  job.target_robot_mm = paused->robot_mm;
  job.paused = *paused->paused;
  job.aimed = paused->commandedJoints();
  for (const auto& t : s.targets) {  // after it in plan order: every target not reached
    if (!t.reached && t.id != paused->id && t.plannable()) {
      job.later.push_back({t.id, t.robot_mm, t.commandedJoints()});
    }
  }
  return job;
}

Input scanNeedle(const NeedleScanJob& job) {
  return proposeReaim(job, measureConfirmation(job.scan));  // it refuses a job without a robot
}

Input proposeReaim(const NeedleScanJob& job, const Input& measured) {
  if (measured.kind != InputKind::kConfirmationMeasured) return failed(job, measured.error);
  if (!job.scan.robot) return failed(job, "no robot to search the markers of");
  const config::Robot& robot = *job.scan.robot;
  const auto& kin = robot.kinematics;

  // The scan's registration: the markers compared with the session's (reused while they moved no
  // more than their localisation explains), or the transform given with the scan.
  const auto reg = detail::registerScan(robot, job.session_registration, measured.points,
                                        job.scan.image_to_robot);
  if (!reg) return failed(job, reg.error().reason + ": " + reg.error().message);
  const Eigen::Matrix4d image_to_robot = reg->registration.imageToRobot();
  auto toRobot = [&](const Eigen::Vector3d& lps) {
    return Eigen::Vector3d((image_to_robot * lps.homogeneous()).head<3>());
  };

  // The paused needle: the tip found nearest where the aim's model puts it.
  const compensation::DeflectionModel aim = aimModel(job);
  auto expected_tip = compensation::predictLanding(kin, aim, job.paused);
  if (!expected_tip) return failed(job, "the aim's model: " + expected_tip.error().message);
  const FoundSeed* tip = nullptr;
  double nearest_mm = std::numeric_limits<double>::infinity();
  for (const auto& seed : measured.seeds) {
    if (seed.kind != "tip" || seed.path_lps_mm.empty()) continue;
    const double d = (toRobot(seed.lps_mm) - expected_tip->tip_mm).norm();
    if (d < nearest_mm) {
      nearest_mm = d;
      tip = &seed;
    }
  }
  if (!tip) {
    return failed(job, fmt::format("no needle on {} ({}): scan with the needle in, stopped at "
                                   "T{}",
                                   job.scan.source, measured.summary, job.target_id));
  }
  if (nearest_mm > kTipSearch_mm) {
    return failed(job, fmt::format("the needle tip found on {} lies {:.1f} mm from where T{}'s "
                                   "paused needle should be (more than {:.0f} mm): another needle, "
                                   "or the scan of another pose",
                                   job.scan.source, nearest_mm, job.target_id, kTipSearch_mm));
  }
  std::vector<Eigen::Vector3d> path_mm;
  for (const auto& p : tip->path_lps_mm)
    path_mm.push_back(toRobot(p));

  // The tissue refitted with this path and the errors measured so far; without a needle model,
  // or when the fit is refused, the aim's model stays.
  ReaimProposal proposal;
  compensation::DeflectionModel model = aim, refit_model = aim;
  std::optional<compensation::TargetingFit> refit;
  const std::string aim_words = job.aim_tissue
                                    ? fmt::format("the aim's tissue '{}'", job.aim_tissue->name)
                                    : std::string("the kinematics' path (no tissue aimed for)");
  if (!job.tissue) {
    proposal.model = aim_words + ": no needle model to refit (server.yaml tissue:)";
  } else {
    auto records = job.records;
    records.push_back({fmt::format("T{} (paused)", job.target_id), expected_tip->tip_mm, job.paused,
                       path_mm.back(), path_mm});
    compensation::DeflectionModel needle;
    needle.needle = job.tissue->needle;
    auto fit = compensation::fitTissueFromTargeting(kin, needle, records);
    if (fit) {
      refit_model.needle = job.tissue->needle;
      refit_model.needle.curvature_per_mm = fit->curvature_per_mm;
      refit_model.tissue = fit->tissue;
      refit = *fit;
      const std::string figures = fmt::format(
          "refitted with this path and {} measured target(s): λ1 {:.3f} ± {:.3f}, λ2 {:.3f} ± "
          "{:.3f}, RMS {:.3f} mm",
          job.records.size(), fit->tissue.lambda1, fit->standard_errors.at(0), fit->tissue.lambda2,
          fit->standard_errors.at(1), fit->rms_mm);
      const double se_mm = landingSe_mm(kin, refit_model, *fit, job.aimed);
      if (se_mm <= kMaxLandingSe_mm) {
        model = refit_model;
        proposal.model =
            fmt::format("the tissue {} (its landing here ± {:.2f} mm)", figures, se_mm);
      } else {
        proposal.model = fmt::format(
            "{} (the tissue {} leaves this landing {})", aim_words, figures,
            std::isfinite(se_mm)
                ? fmt::format("uncertain by ± {:.2f} mm, more than {:.2f}", se_mm, kMaxLandingSe_mm)
                : std::string("undetermined (a λ on the model's admissibility limit)"));
      }
    } else {
      proposal.model = aim_words + " (the refit was refused: " + fit.error().message + ")";
    }
  }

  auto reaim = compensation::reaimFromPath(kin, model, job.paused, path_mm, job.target_robot_mm);
  if (!reaim)
    return failed(job, "the re-aim from T" + std::to_string(job.target_id) +
                           "'s path: " + reaim.error().message);
  proposal.job = job.scan.job;
  proposal.source = job.scan.source;
  proposal.target_id = job.target_id;
  proposal.paused = job.paused;
  proposal.tip_lps_mm = tip->lps_mm;
  proposal.tip_robot_mm = path_mm.back();
  proposal.tip_offset_mm = reaim->tip_offset_mm;
  proposal.path_rms_mm = reaim->path_rms_mm;
  proposal.path_points = reaim->pairs;
  ReaimedAim here;
  here.target_id = job.target_id;
  here.how = "path";
  here.before = job.aimed;
  here.joints = reaim->aimed.compensated;
  here.landing_robot_mm = reaim->landing_mm;
  if (auto before = compensation::predictLanding(kin, model, job.aimed)) {
    here.before_landing_robot_mm =
        (reaim->correction * before->tip_mm.homogeneous()).head<3>();  // as the path showed
  }
  proposal.aims.push_back(here);
  std::string later_words;
  if (refit) {
    for (const auto& t : job.later) {
      // Each later target only where the refit determines its landing.
      const double se_mm = landingSe_mm(kin, refit_model, *refit, t.aimed);
      if (!(se_mm <= kMaxLandingSe_mm)) {
        later_words += fmt::format(
            "; T{} keeps its aim (the refit's landing there is {})", t.id,
            std::isfinite(se_mm) ? fmt::format("± {:.2f} mm", se_mm) : std::string("undetermined"));
        continue;
      }
      auto c = compensation::compensate(kin, refit_model, t.robot_mm);
      if (!c) {
        later_words += fmt::format("; T{} keeps its aim ({})", t.id, c.error().message);
        continue;
      }
      ReaimedAim a;
      a.target_id = t.id;
      a.how = "refit";
      a.before = t.aimed;
      a.joints = c->compensated;
      a.landing_robot_mm = c->compensated_landing_mm;
      if (auto before = compensation::predictLanding(kin, refit_model, t.aimed)) {
        a.before_landing_robot_mm = before->tip_mm;
      }
      proposal.aims.push_back(a);
    }
  } else if (!job.later.empty()) {
    later_words = "; the targets after it keep their aim (no refitted tissue)";
  }
  proposal.message = fmt::format(
      "T{}'s needle on {}: tip {:.2f} mm from the model's, path RMS {:.3f} mm over {} points "
      "after the correction; re-aimed with {}: {} (was {}), predicted to land {:.4f} mm from the "
      "target (as aimed before: {:.2f} mm){}{}",
      job.target_id, job.scan.source, proposal.tip_offset_mm, proposal.path_rms_mm,
      proposal.path_points, proposal.model, jointsText(here.joints), jointsText(here.before),
      (here.landing_robot_mm - job.target_robot_mm).norm(),
      (here.before_landing_robot_mm - job.target_robot_mm).norm(),
      proposal.aims.size() > 1 ? fmt::format("; {} later target(s) aimed for the refitted tissue",
                                             proposal.aims.size() - 1)
                               : std::string(),
      later_words);

  Input in;
  in.kind = InputKind::kNeedleScanned;
  in.job = job.scan.job;
  in.path = job.scan.source;
  in.points = measured.points;
  in.seeds = measured.seeds;
  in.summary = measured.summary;
  in.reaim = std::move(proposal);
  return in;
}

namespace detail {

double landingSe_mm(const kinematics::Kinematics& kin, const compensation::DeflectionModel& model,
                    const compensation::TargetingFit& fit, const kinematics::Joints& joints) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double s1 = fit.standard_errors.at(0), s2 = fit.standard_errors.at(1);
  const double rho = std::isfinite(fit.correlation) ? fit.correlation : 0.0;
  Eigen::Matrix2d covariance;
  covariance << s1 * s1, rho * s1 * s2, rho * s1 * s2, s2 * s2;
  if (!covariance.allFinite()) return kInf;
  constexpr double kStep = 1e-4;
  Eigen::Matrix<double, 3, 2> jacobian;
  for (int p = 0; p < 2; ++p) {
    Eigen::Vector3d ends[2];
    for (int side = 0; side < 2; ++side) {
      compensation::DeflectionModel moved = model;
      double& lambda = p == 0 ? moved.tissue.lambda1 : moved.tissue.lambda2;
      lambda += side == 0 ? kStep : -kStep;
      auto landing = compensation::predictLanding(kin, moved, joints);
      if (!landing) return kInf;
      ends[side] = landing->tip_mm;
    }
    jacobian.col(p) = (ends[0] - ends[1]) / (2.0 * kStep);
  }
  return std::sqrt((jacobian * covariance * jacobian.transpose()).trace());
}

}  // namespace detail
}  // namespace ignav::workflow
