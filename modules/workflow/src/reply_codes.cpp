#include "ignav/workflow/reply_codes.hpp"

#include <stdexcept>

#include "ignav/core/table_order.hpp"

namespace ignav::workflow {
namespace {

using C = ReplyCode;

const std::vector<ReplyCodeSpec> kCodes = {
    {C::kWrongPhase, "wrong_phase",
     "the command is not allowed in this phase: \"add_target is not allowed in imaging "
     "(allowed: load_volume, stop, …)\""},
    {C::kBadArguments, "bad_arguments",
     "the command does not carry what its row in the table of commands names (points, ids, "
     "path, matrix)"},
    {C::kNonFinite, "non_finite",
     "NaN or ±inf in `points[i]`, or in a matrix (`set_registration`, `load_confirmation`)"},
    {C::kOversized, "oversized", "more than 100 points or ids"},
    {C::kTooLong, "too_long", "path over 4096 characters, or a digest over 128"},
    {C::kBadClientId, "bad_client_id", "client_id empty or over 128 characters"},
    {C::kBadText, "bad_text",
     "client_id or path is not well-formed UTF-8: \"client_id is not UTF-8 text (byte 2 is "
     "0xF5)\""},
    {C::kUnknownCommand, "unknown_command",
     "a `kind` that is no command's (4096, 99, 2³¹−1, −1, ...)"},
    {C::kNotPermitted, "not_permitted",
     "a command on the topic of a role below its own; also a DDS client using the client id "
     "`openigtlink`, which belongs to the OpenIGTLink bridge (docs/OPENIGTLINK.md)"},
    {C::kBadPath, "bad_path", "the server cannot see the path"},
    {C::kBusy, "busy",
     "a volume is already loading; or the markers are being detected (a second auto_fiducials, "
     "or lock_plan while the registration may still change)"},
    {C::kUnknownTarget, "unknown_target", "\"no target 999\""},
    {C::kOutsideVolume, "outside_volume",
     "`add_target` or `move_target` to a point outside the loaded CT's imaged box (every voxel "
     "with its half-voxel margin), from any transport: \"target (-134.0, -114.0, -18.0) mm LPS "
     "lies 103.9 mm outside the loaded CT (phantom:): only imaged tissue can be targeted\"; "
     "`lock_plan` while a target lies outside a CT loaded after it was placed. Without a CT here "
     "(a registration set by 3D Slicer, which holds the images) targets are not checked"},
    {C::kBadOrder, "bad_order", "reorder without every id exactly once"},
    {C::kTooManyTargets, "too_many_targets", "the plan has 100 targets already (paper §V)"},
    {C::kEmptyPlan, "empty_plan", "lock refused: there are no targets"},
    {C::kUnreachableTargets, "unreachable_targets",
     "lock refused, listing each unreachable target with its reason"},
    {C::kRotationLimit, "rotation_limit",
     "the targets' order turns the cannula more than 360° in all (a user's `reorder_targets` "
     "can; so can the server's best order from where the cannula stands, e.g. targets all round "
     "the axis after an earlier insertion)"},
    {C::kNothingToDo, "nothing_to_do", "every target was reached and the stylet is home"},
    {C::kPlanFailed, "plan_failed",
     "no plan from where the robot stands (e.g. a pose outside the joint ranges after a stall)"},
    {C::kNoVolume, "no_volume", "automatic fiducials without a CT"},
    {C::kNoMatch, "no_match", "automatic fiducials: no marker triple matches the robot's"},
    {C::kBadSearch, "bad_search", "automatic fiducials: the search settings cannot work"},
    {C::kTooFewPairs, "too_few_pairs", "registration: fewer than 3 point pairs"},
    {C::kCountMismatch, "count_mismatch", "registration: image and robot point counts differ"},
    {C::kCoincident, "coincident", "registration: two fiducials (nearly) coincide"},
    {C::kCollinear, "collinear", "registration: the fiducials are (nearly) on one line"},
    {C::kScaleOutOfRange, "scale_out_of_range",
     "registration: the scale is outside the configured limits (docs/REGISTRATION.md)"},
    {C::kFreTooLarge, "fre_too_large",
     "registration: the fiducial registration error is too large"},
    {C::kOutOfRange, "out_of_range",
     "a coordinate beyond ±10⁶ mm, or a registration value beyond its limit"},
    {C::kNotAffine, "not_affine",
     "`set_registration`, `load_confirmation`: the matrix's last row is not 0 0 0 1"},
    {C::kNotSimilarity, "not_similarity",
     "`set_registration`, `load_confirmation`: the matrix shears or scales unevenly (singular "
     "values differ by more "
     "than 1e-4)"},
    {C::kMirror, "mirror",
     "`set_registration`, `load_confirmation`: the matrix mirrors (RAS and LPS mixed up?)"},
    {C::kNotRegistered, "not_registered", "`check_ready targeting` before any registration"},
    {C::kStaleDetection, "stale_detection",
     "a marker detection's result for a CT or a request no longer current (another CT loaded, or "
     "set_fiducials / set_registration came meanwhile): ignored, nothing changes. A server "
     "input, logged; no client sends it"},
    {C::kNoPendingApproval, "no_pending_approval", "nothing waits for approval"},
    {C::kStalePlan, "stale_plan",
     "the plan id is not the pending one (any change since killed it)"},
    {C::kNotApprover, "not_approver", "the client id is not in `approval.approvers`"},
    {C::kWrongDigest, "wrong_digest", "the digest is not exactly the one shown"},
    {C::kExpired, "expired",
     "the request is older than `approval.expiry_s`; send `request_approval`"},
    {C::kControllerUnavailable, "controller_unavailable", "the controller does not answer"},
    {C::kControllerBusy, "controller_busy", "the controller still moves"},
    {C::kControllerFault, "controller_fault", "the controller reports a fault"},
    {C::kControllerChanged, "controller_changed",
     "the motors are not where the request starts (someone moved them)"},
    {C::kPositionMismatch, "position_mismatch",
     "leaving stop, emergency or fault: the motors are off the interrupted move, or away from "
     "the last verified position; home the robot"},
    {C::kSuperseded, "superseded",
     "an input that waited for a fresh reading of the controller (approve, resume, "
     "reset_emergency, home, manual, check_ready, and client commands queued behind one) was "
     "overtaken by an emergency stop and not done. Such inputs are answered once the controller "
     "has been read after every command already sent to it: with a slow controller, up to one "
     "reading later (docs/ARCHITECTURE.md)"},
    {C::kNothingReached, "nothing_reached",
     "`load_confirmation` (or a seed command) before any target was reached: a confirmation CT "
     "measures the seeds of reached targets"},
    {C::kNoConfirmation, "no_confirmation",
     "a seed command or `fit_tissue` without a measured confirmation CT "
     "(VerificationState.status none, or unmatched for `fit_tissue`)"},
    {C::kUnknownSeed, "unknown_seed", "\"no seed 12 on the confirmation CT (seeds 1-9)\""},
    {C::kUnknownTissue, "unknown_tissue",
     "`use_tissue` with a name that is neither the configured tissue nor one fitted in this "
     "session; the message lists them"},
    {C::kFitFailed, "fit_failed",
     "`fit_tissue`: the errors do not determine the tissue (too few targets, all at one depth), "
     "the fit does not converge, or no needle model is configured (server.yaml tissue:)"},
    {C::kBadName, "bad_name",
     "a tissue profile's name that is not 1-64 letters, digits, '_' or '-'"},
    {C::kBadDepth, "bad_depth",
     "`pause_at`: a depth that is not a number of mm more than 0 and less than the target's "
     "stylet depth (or none)"},
    {C::kNotPaused, "not_paused",
     "`scan_needle` with no needle stopped part-way (pause_at, then its motion approved), or a "
     "re-aim for an insertion that is no longer paused"},
    {C::kNoReaim, "no_reaim",
     "`reaim` with no re-aim proposed (scan_needle first), or one that would break the plan (a "
     "joint out of range, the rotation limit): the message says which"},
    {C::kNoStructures, "no_structures",
     "`structure_role` or `propose_targets` before any structures are loaded (load_structures); "
     "`load_structures` without a CT"},
    {C::kUnknownStructure, "unknown_structure",
     "`structure_role` or `propose_targets` with a name no loaded structure has; the message "
     "lists them"},
    {C::kBadRole, "bad_role",
     "`structure_role` text that is not NAME ROLE [MARGIN_MM]: a role other than target, avoid, "
     "shown, or a margin that is not 0-10 mm (avoid needs one)"},
    {C::kTooClose, "too_close",
     "`lock_plan` while a target's needle passes closer to an avoided structure than its margin "
     "(after the uncertainty there): the message names the target, the structure, the distance, "
     "the margin, the uncertainty and the point; override_clearance plans it all the same"},
    {C::kNotTooClose, "not_too_close",
     "`override_clearance` for a target whose clearances all hold"},
    {C::kNoReason, "no_reason", "`override_clearance` without a reason"},
    {C::kBadSpacing, "bad_spacing",
     "`propose_targets`: no structure name and spacing, a spacing outside 1-30 mm, or one so "
     "fine the lattice has too many points to try"},
    {C::kNoProposals, "no_proposals", "`accept_proposals` with no targets proposed"},
    {C::kUnknownProposal, "unknown_proposal", "`accept_proposals` names no proposed target"},
    {C::kBadApproach, "bad_approach",
     "`place_robot` naming a side the needle cannot come from (not inferior, superior, anterior, "
     "posterior, left or right)"},
    {C::kBadSeedPlan, "bad_seed_plan",
     "`plan_seeds` (and `compute_dose`): no structure, a word that is not model=, rx=, strength= "
     "or spacing=, a "
     "prescription outside 0-1000 Gy, a seed strength outside 0.05-10 U, a spacing outside "
     "2-15 mm, or a structure that is not a target"},
    {C::kUnknownSeedModel, "unknown_seed_model",
     "`plan_seeds` naming a seed model the site's seed models folder does not hold, or a site "
     "with no dosimetry: block"},
    {C::kNoDoseToCompute, "nothing_to_dose",
     "`compute_dose` with no plannable targets and no confirmation CT's seeds, or no structure "
     "named to judge the dose on when no seed plan was accepted"},
    {C::kJournalFailed, "journal_failed",
     "the session journal cannot be written (disk full, I/O error): nothing was done, and every "
     "later change is refused until the server is restarted; `Health.journal` says why "
     "(docs/RELIABILITY.md)"},
    {C::kInternal, "internal", "a bug: the server refused rather than act on it (please report)"},
};

}  // namespace

const std::vector<ReplyCodeSpec>& replyCodeTable() {
  static const bool ok = inEnumOrder(kCodes, &ReplyCodeSpec::code);
  if (!ok) throw std::logic_error("reply code table is not in ReplyCode order");
  return kCodes;
}

const char* toString(ReplyCode code) {
  return replyCodeTable().at(static_cast<std::size_t>(code)).name;
}

std::optional<ReplyCode> replyCodeNamed(std::string_view name) {
  for (const auto& c : replyCodeTable())
    if (name == c.name) return c.code;
  return std::nullopt;
}

std::string replyCodesMarkdown() {
  std::string out = "| code | meaning |\n|---|---|\n";
  for (const auto& c : replyCodeTable())
    out += std::string("| `") + c.name + "` | " + c.meaning + " |\n";
  return out;
}

}  // namespace ignav::workflow
