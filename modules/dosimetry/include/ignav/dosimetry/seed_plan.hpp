// A seed plan (issue 42, part 3): among the positions a seed may go (reachable with every
// clearance kept), the fewest seeds of one strength whose permanent-implant dose covers the
// target (V100, D90) while each organ at risk stays within its limits (D10, D2cc, Dmax).
//
// How: GLPK's simplex solves the linear relaxation (a weight in 0-1 per candidate, the target's
// under-dose and the organs' over-dose as penalised slacks) on a sample of the structures'
// voxels; its weights, rounded, start a repair (add the candidate that newly covers the most of
// the target without breaking an organ's limit, drop the hottest contributor to a broken one)
// and a prune (drop any seed the constraints do without), judged on a finer sample; the result
// is then judged on every voxel and repaired again if that sample was too kind. Every constraint
// is a count of voxels above a dose (D90 ≥ x ⟺ at least ⌈0.9 n⌉ voxels get x), so checking a
// candidate costs one pass over the sample.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "ignav/core/expected.hpp"
#include "ignav/dosimetry/dose_grid.hpp"
#include "ignav/dosimetry/dvh.hpp"
#include "ignav/dosimetry/organ_limits.hpp"

namespace ignav::dosimetry {

// A structure as dose sees it: its voxels' centres (LPS), each `voxel_cm3`.
struct DoseStructure {
  std::string name;
  std::vector<Eigen::Vector3d> voxels_lps_mm;
  double voxel_cm3 = 0.0;
};

struct OrganAtRisk {
  DoseStructure structure;
  OrganLimits limits;
};

// Seed strengths a plan accepts (air-kerma strength, U = µGy m² h⁻¹): clinical I-125 and
// Pd-103 seeds lie well inside.
constexpr double kMinSeedStrength_U = 0.05;
constexpr double kMaxSeedStrength_U = 10.0;

struct SeedPlanRequest {
  std::shared_ptr<const DoseRateTable> table;  // the seed model, tabulated
  double strength_U = 0.0;                     // every seed's
  double prescription_Gy = 0.0;                // the dose the target must receive
  DoseStructure target;
  std::vector<OrganAtRisk> organs;
  std::vector<Seed> candidates;  // where a seed may go, each with its axis
  // Seeds already in the patient (re-planning during the implant, from the confirmation CT):
  // their dose is there before any candidate's; the plan chooses the seeds to add.
  std::vector<Seed> implanted;
  double min_v100 = 0.95;  // fraction of the target at ≥ 100 %
  double min_d90_percent = 100.0;
  std::size_t max_seeds = 100;  // the plan's targets per insertion
};

// Errors name the field: no table, strength outside kMin-kMaxSeedStrength_U (`bad_strength`),
// prescription ≤ 0 or not finite (`bad_prescription`), an empty structure (`empty_structure`),
// no candidates or a non-finite one (`no_candidates`, `bad_candidate`), goals out of range
// (`bad_goal`), a limit ≤ 0 (`bad_limit`).
Status validate(const SeedPlanRequest& request);

struct OrganResult {
  std::string name;
  OrganMetrics metrics;
  OrganLimits limits;
};

// A structure's cumulative DVH on 1 Gy bins (the fraction receiving at least k Gy), up to three
// prescriptions: for plots and exchange.
struct StructureCurve {
  std::string name;
  std::vector<double> cumulative;
};
constexpr double kCurveBin_Gy = 1.0;

// A set of seeds, with the request's implanted ones, judged on every voxel of its structures.
// Errors as validate's, but the request needs no candidates (`seeds` need not be among them); a
// seed not finite (bad_candidate).
struct PlanEvaluation {
  TargetMetrics target;
  double target_cm3 = 0.0;
  std::vector<OrganResult> organs;
  std::vector<StructureCurve> curves;  // the target's, then each organ's
  std::vector<std::string> unmet;      // each constraint missed, e.g. "urethra D10 162.3 % > 150 %"
  bool met() const { return unmet.empty(); }
  std::string describe() const;  // "V100 96.1 %, D90 104.2 %; urethra D10 131.0 %, …"
};
Expected<PlanEvaluation> evaluatePlan(const SeedPlanRequest& request,
                                      const std::vector<Seed>& seeds);

struct SeedPlan {
  std::vector<std::size_t> chosen;  // indices into the request's candidates, ascending
  PlanEvaluation evaluation;
  double relaxed_seeds = 0.0;  // the linear relaxation's Σ weights: a floor for the count
  // Re-planning: each organ's limit the implanted seeds already exceed, and what it became
  // ("urethra D10 160.2 % delivered already, held to 165.2 %").
  std::vector<std::string> raised_limits;
};

// Re-planning: an organ the implanted seeds already take over a limit may rise this many points
// of the prescription above what it has (its dose cannot be taken back; the target's cannot be
// recovered without adding some).
constexpr double kReplanRise_percent = 5.0;
// `stage` names what runs: "dose per candidate", "linear programme", "repair", "every voxel".
using PlanProgress =
    std::function<void(std::size_t done, std::size_t total, std::string_view stage)>;
// The plan, or `infeasible_plan` naming the constraints no choice among the candidates met
// (and what the best choice reached), or `too_many_seeds`. With implanted seeds that already
// meet every goal, a plan of no seeds; with implanted seeds over an organ's limit, that limit is
// raised to what they give plus kReplanRise_percent (SeedPlan::raised_limits).
Expected<SeedPlan> planSeeds(const SeedPlanRequest& request, const PlanProgress& progress = {});

// The usual baseline: seeds spread evenly through the target (no two candidates nearer than
// `spacing_mm`, taken in the candidates' order), at the widest spacing (from 20 mm down in
// 0.5 mm steps) whose V100 and D90 meet the goals; organs are not considered. Fails
// (`infeasible_plan`) when even every candidate does not cover the target.
struct UniformLoading {
  double spacing_mm = 0.0;
  std::vector<std::size_t> chosen;
  PlanEvaluation evaluation;
};
Expected<UniformLoading> uniformLoading(const SeedPlanRequest& request);

// Where the target is cold: its voxels below the prescription, joined into regions (voxels no
// farther apart than 1.5 voxel sides), the largest first, those of at least `min_cm3`.
struct ColdSpot {
  Eigen::Vector3d centroid_lps_mm = Eigen::Vector3d::Zero();
  double volume_cm3 = 0.0;
  double min_dose_Gy = 0.0;  // its coldest voxel's
};
Expected<std::vector<ColdSpot>> coldSpots(const SeedPlanRequest& request,
                                          const std::vector<Seed>& seeds, double min_cm3 = 0.05);

}  // namespace ignav::dosimetry
