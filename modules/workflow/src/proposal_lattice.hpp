// Candidate targets in a structure (target_proposal.cpp), shared by propose_targets and plan_seeds:
// a lattice's points in it, and which of them the plan would take.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/workflow/session.hpp"

namespace ignav::workflow {

// What every proposal's job starts from: its failure (target_proposal_failed naming `job`), and
// the structure it fills on the snapshot; none, with the failure's error, when it or the
// registration is missing (the command checked both: the snapshot is the same).
struct ProposalStart {
  Input failed;
  const anatomy::Structure* structure = nullptr;
};
ProposalStart startProposal(std::uint64_t job, const std::string& structure, double spacing_mm,
                            const Session& s);

// The points of a lattice of `spacing_mm` inside `mask` (LPS): along the robot's axes (its
// insertion along z, so points come in layers the stylet reaches alike), through the mask's
// centroid, over its box in that frame. None when more than kMaxProposalCandidates.
std::optional<std::vector<Eigen::Vector3d>> latticeIn(const anatomy::Mask& mask,
                                                      const registration::Registration& reg,
                                                      double spacing_mm);

// The candidates a target there would be planned for (reachable, aimed, every clearance kept),
// in their order, and the others counted by why not.
struct Judged {
  std::vector<Target> kept;
  std::string left_out;  // "12 out of the needle's reach, 4 too close to 'urethra'"
};
Judged judge(const Session& s, const std::vector<Eigen::Vector3d>& candidates,
             const std::function<void(std::size_t, std::size_t)>& progress);

// Their points in the order the plan visits them from where the robot is (lock_plan orders them
// again with the targets already planned), and the cannula's turning on the way.
struct VisitOrder {
  std::vector<Eigen::Vector3d> points;
  double rotation_rad = 0.0;
};
VisitOrder visitOrder(const Session& s, const std::vector<Target>& targets);

}  // namespace ignav::workflow
