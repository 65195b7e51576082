// Every error code a reply can carry, declared once with what it means (issue 22: codes are an
// enum, not strings spelled where they are used). Reply.error_code carries the name on the wire;
// docs/PROTOCOL.md's table of codes is generated from this one (reply_codes.cpp).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace ignav::workflow {

enum class ReplyCode {
  // The shape of a command (the input table's argument rules and the limits).
  kWrongPhase,
  kBadArguments,
  kNonFinite,
  kOversized,
  kTooLong,
  kBadClientId,
  kBadText,
  kUnknownCommand,
  kNotPermitted,
  // Volumes and targets.
  kBadPath,
  kBusy,
  kUnknownTarget,
  kOutsideVolume,
  kBadOrder,
  kTooManyTargets,
  kEmptyPlan,
  kUnreachableTargets,
  kRotationLimit,
  kNothingToDo,
  kPlanFailed,
  // Registration (the reasons modules/registration gives, and automatic fiducials).
  kNoVolume,
  kNoMatch,
  kBadSearch,
  kTooFewPairs,
  kCountMismatch,
  kCoincident,
  kCollinear,
  kScaleOutOfRange,
  kFreTooLarge,
  kOutOfRange,
  kNotAffine,
  kNotSimilarity,
  kMirror,
  kNotRegistered,
  kStaleDetection,
  // Approval.
  kNoPendingApproval,
  kStalePlan,
  kNotApprover,
  kWrongDigest,
  kExpired,
  // The controller.
  kControllerUnavailable,
  kControllerBusy,
  kControllerFault,
  kControllerChanged,
  kPositionMismatch,
  kSuperseded,
  // The closed loop (issue 23): confirmation CT, seeds, tissue fits, compensated aiming.
  kNothingReached,
  kNoConfirmation,
  kUnknownSeed,
  kUnknownTissue,
  kFitFailed,
  kBadName,
  // Re-planning during an insertion (issue 40).
  kBadDepth,
  kNotPaused,
  kNoReaim,
  // The patient's structures and the needle's clearance (issue 41).
  kNoStructures,
  kUnknownStructure,
  kBadRole,
  kTooClose,
  kNotTooClose,
  kNoReason,
  kBadSpacing,
  kNoProposals,
  kUnknownProposal,
  kBadApproach,
  // Dose (issue 42).
  kBadSeedPlan,
  kUnknownSeedModel,
  kNoDoseToCompute,
  // The server.
  kJournalFailed,
  kInternal,
};

struct ReplyCodeSpec {
  ReplyCode code;
  const char* name;     // on the wire: "wrong_phase", ...
  const char* meaning;  // for docs/PROTOCOL.md
};

const std::vector<ReplyCodeSpec>& replyCodeTable();  // in ReplyCode order
const char* toString(ReplyCode code);
// The code a name stands for (modules/registration reports its reasons by name).
std::optional<ReplyCode> replyCodeNamed(std::string_view name);

// Why the workflow refused an input: the reply's code and a message a person can act on.
struct Rejection {
  ReplyCode code;
  std::string message;
};
// docs/PROTOCOL.md's table of codes.
std::string replyCodesMarkdown();

}  // namespace ignav::workflow
