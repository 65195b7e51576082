// The workflow's inputs are the command table's (ignav/commands/command_table.hpp, std only, so
// that clients build without the workflow stack): its names, used here as the workflow's own.
#pragma once

#include "ignav/commands/command_table.hpp"

namespace ignav::workflow {

using commands::Arguments;
using commands::ClientRole;
using commands::InputKind;
using commands::InputSpec;
using commands::InputTraits;
using commands::kAnyCount;
using commands::kEveryPhase;
using commands::kFromClients;
using commands::kNeedsReading;
using commands::kNoWireKind;
using commands::kPlain;
using commands::kQuestion;
using commands::kReleasesMotion;

using commands::commandNamed;
using commands::commandOfWireKind;
using commands::inputTable;
using commands::isCommand;
using commands::isQuestion;
using commands::needsControllerReading;
using commands::releasesMotion;
using commands::specOf;
using commands::toString;
using commands::usageOf;

}  // namespace ignav::workflow
