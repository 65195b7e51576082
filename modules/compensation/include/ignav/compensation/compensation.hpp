// Aiming with the deflection model (issue 23): where the stylet tip lands when the cannula drifts
// in tissue as the extended bicycle model predicts, the joints that make it land on a target, and
// the tissue fitted from measured targeting errors. Convention: docs/COMPENSATION.md (the
// addendum to MODEL.md §10). Pure functions over kinematics + deflection: values in, values out.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/deflection/bicycle_model.hpp"
#include "ignav/kinematics/instrument.hpp"
#include "ignav/kinematics/solver.hpp"

namespace ignav::compensation {

// How the stylet leaves a cannula whose tip the tissue has turned.
enum class StyletCarry {
  kRotated,     // along the turned cannula: its nominal path turns with the tip (canonical)
  kTranslated,  // shifted with the cannula tip only (the cannula drift alone, as evaluate() shows)
};

// The needle model and tissue as configs/tissues.yaml gives them, plus the carry convention.
struct DeflectionModel {
  deflection::NeedleModel needle;
  deflection::Tissue tissue;
  StyletCarry carry = StyletCarry::kRotated;
};

// The cannula after z_c mm pushed into tissue, in the plane of θc, against the straight nominal
// push. The model's bend (k < 0: its −y) points to +y′, the side the stylet curves to.
struct CannulaDrift {
  double lateral_mm = 0.0;    // towards +y′ (= −y of the model; evaluate()'s drift is −this)
  double shortfall_mm = 0.0;  // less deep than nominal: z_c − z_model(z_c) ≥ 0
  double heading_rad = 0.0;   // the tip turned from −Z towards +y′ (= −γ of the model)
};
// Zero for z_c ≤ 0 (not in tissue). Errors: an inadmissible tissue, a path turning past 90°.
Expected<CannulaDrift> cannulaDrift(const DeflectionModel& model, double z_c_mm);

struct Landing {
  Eigen::Vector3d tip_mm = Eigen::Vector3d::Zero();          // predicted stylet tip
  Eigen::Vector3d cannula_tip_mm = Eigen::Vector3d::Zero();  // predicted cannula tip
  Eigen::Vector3d nominal_tip_mm = Eigen::Vector3d::Zero();  // forward kinematics, no tissue
  CannulaDrift drift;
};
// The predicted landing point of the stylet tip in the robot frame for joints (not range-checked,
// like Kinematics::forward).
Expected<Landing> predictLanding(const kinematics::Kinematics& kinematics,
                                 const DeflectionModel& model, const kinematics::Joints& joints);

// The whole needle for joints, robot frame, about every step_mm of arc: the cannula from
// `above_mm` above the tissue to its tip, then the stylet. Out of tissue it is the instrument's
// own shape (Kinematics::centreline); in tissue each point of the cannula is displaced as its tip
// was when that point went in (the bicycle model's needle follows its tip), and the stylet turns
// with the cannula tip as predictLanding turns it. The last cannula point is
// Landing::cannula_tip_mm and the last stylet point Landing::tip_mm. What a confirmation CT that
// still shows the needle is compared with (docs/COMPENSATION.md, "The path").
struct PredictedPath {
  std::vector<Eigen::Vector3d> cannula_mm;
  std::vector<Eigen::Vector3d> stylet_mm;
};
// Errors: non-finite joints or step, a step not in [0.01, 10] mm, the model's own (as
// predictLanding).
Expected<PredictedPath> predictPath(const kinematics::Kinematics& kinematics,
                                    const DeflectionModel& model, const kinematics::Joints& joints,
                                    double step_mm = 0.5, double above_mm = 0.0);

struct CompensationOptions {
  double tolerance_mm = 1e-6;  // accepted |landing − target| (the issue asks ≤ 1 µm = 1e-3 mm)
  int max_iterations = 30;     // Newton steps on the joints
};

struct Compensation {
  kinematics::InverseSolution nominal;     // exact IK of the target (no tissue)
  Eigen::Vector3d nominal_landing_mm;      // where the nominal joints land (NaN: no joints)
  kinematics::Joints compensated;          // joints whose predicted landing is the target
  Eigen::Vector3d compensated_landing_mm;  // their predicted landing
  double residual_mm = 0.0;                // |compensated_landing − target|
  int iterations = 0;                      // Newton steps taken (0: nothing to compensate)
};
// Newton on the joints, from the exact IK of the target, with a finite-difference Jacobian, a
// trust region and step halving. Refused (reason "compensated_out_of_reach") when the
// compensated joints, or those where the iteration stalls, leave their ranges, naming the joint
// and the limit; "not_converged" when it stalls inside them; "inadmissible" for the tissue.
Expected<Compensation> compensate(const kinematics::Kinematics& kinematics,
                                  const DeflectionModel& model, const Eigen::Vector3d& target_mm,
                                  const CompensationOptions& options = {});

// The rest of an insertion re-aimed from where the needle is (issue 40, step 6): it stopped part
// way at `partial` and an intermittent CT shows its shape (`observed_path_mm`, robot frame, from
// where it enters the tissue to the stylet's tip). What the insertion does beyond the model shows
// as the rigid motion that carries the model's path for `partial` onto the observed one, fitted
// by iterated closest points (the observed path thinned to a point a millimetre, each paired with
// the nearest point of the moved model path, the tips paired with a quarter of the weight,
// Eigen::umeyama without scale each round). The rest is aimed so that the model's landing,
// carried by that motion, is the target: the target carried back, compensated as any target is.
struct Reaim {
  Eigen::Matrix4d correction = Eigen::Matrix4d::Identity();  // model's path -> observed, robot
  double tip_offset_mm = 0.0;  // observed tip − the model's, before the correction
  double path_rms_mm = 0.0;    // observed points vs the corrected model path, over the pairs
  std::size_t pairs = 0;       // observed points compared
  Compensation aimed;          // for the target carried back
  Eigen::Vector3d landing_mm = Eigen::Vector3d::Zero();  // the aimed joints' landing, corrected
};
// Errors: non-finite input, a path shorter than 3 mm or than 4 points (nothing to fit a motion
// to), the model's (as predictPath), compensate's (out of reach, not converged).
Expected<Reaim> reaimFromPath(const kinematics::Kinematics& kinematics,
                              const DeflectionModel& model, const kinematics::Joints& partial,
                              const std::vector<Eigen::Vector3d>& observed_path_mm,
                              const Eigen::Vector3d& target_mm,
                              const CompensationOptions& options = {});

// One seed or tip measured after a move: what was planned, the joints used, where it ended.
struct TargetingRecord {
  std::string id;
  Eigen::Vector3d planned_mm = Eigen::Vector3d::Zero();  // robot frame
  kinematics::Joints joints;                             // as commanded (nominal or compensated)
  Eigen::Vector3d actual_mm = Eigen::Vector3d::Zero();   // measured, robot frame
  // Where the CT still shows the needle (a stylet tip found rather than a seed): points on its
  // centreline, robot frame, each compared with the nearest point of predictPath. Empty: none.
  std::vector<Eigen::Vector3d> path_mm;
};

struct TargetingFitOptions {
  deflection::Tissue initial{0.2, 0.1};
  bool fit_curvature = false;  // also fit the needle's k
  int max_evaluations = 400;   // of the residuals per start, before a start counts as not converged
  // Runs of Levenberg–Marquardt beyond two, from the lowest starts (fitTissueFromTargeting).
  int grid_starts = 3;
  // A fit whose predicted landings are uncertain (1 SE, RMS over the targets) by more than this
  // fraction of the deflection it predicts has not determined its parameters: refused.
  double max_prediction_uncertainty = 0.5;
};

struct TargetingFit {
  deflection::Tissue tissue;
  double curvature_per_mm = 0.0;        // fitted, or the model's
  std::vector<double> standard_errors;  // λ1, λ2 [, k]; σ² = RSS / (3n − p)
  double correlation = 0.0;             // λ1–λ2
  double rms_mm = 0.0;                  // 3-D, of actual − predicted landing per target
  double max_error_mm = 0.0;
  double rms_bicycle_mm = 0.0;  // the plain bicycle model (λ = 0, k fitted) on the same data
  double max_error_bicycle_mm = 0.0;
  double bicycle_curvature_per_mm = 0.0;
  double rms_no_deflection_mm = 0.0;  // actual − forward kinematics: the errors as measured
  // What the fitted tissue predicts, RMS over the targets: its landings' distance from forward
  // kinematics, and their standard error from the parameters' covariance.
  double predicted_deflection_mm = 0.0;
  double prediction_se_mm = 0.0;
  int iterations = 0;  // of the start that won
  int starts = 0;      // Levenberg–Marquardt runs made
  std::string start;   // which one won: "the guess", "the plain model", "grid (λ1, λ2)"
  // Non-empty when a parameter ends on the model's admissibility limit (checkAdmissible over
  // γ ∈ [−π/2, 0]): which one, and why. The estimate is then bounded, not determined.
  std::string limit;
};
// Levenberg–Marquardt on the 3-D residuals actual − predictLanding(joints), each target at its own
// insertion depth and in its own plane, and for a record with a path, each path point's offset
// from the nearest point of the predicted path (rms_mm and the maxima are over the landings).
// Several starts, the lowest end wins: the guess, the plain model it extends (λ = 0, with the
// curvature the plain fit found when k is fitted too) and the points of deflection::tissueGrid,
// tried lowest sum of squares first while a start lies below the best end so far (at most
// grid_starts + 2 runs); so it never ends worse than the model it extends.
// Refused: non-finite records, fewer residuals than parameters, records that do not determine the
// parameters (no insertion, all at one depth, or landings the covariance leaves uncertain by more
// than max_prediction_uncertainty of the deflection: reason "underdetermined"), a fit that explains
// the errors no better than no deflection at all ("explains_nothing"), a fit that does not
// converge from any start ("not_converged") or ends inadmissible. Each refusal gives the figures.
Expected<TargetingFit> fitTissueFromTargeting(const kinematics::Kinematics& kinematics,
                                              const DeflectionModel& model,
                                              const std::vector<TargetingRecord>& records,
                                              const TargetingFitOptions& options = {});

// The fit as a named entry under `tissues:` of configs/tissues.yaml (with `curvature_per_mm`
// when the curvature was fitted), e.g. "  session_12:\n    lambda1: ...\n". The name must be
// letters, digits, '_' or '-'.
Expected<std::string> tissueProfileYaml(const std::string& name, const TargetingFit& fit,
                                        const std::string& source, bool with_curvature);

}  // namespace ignav::compensation
