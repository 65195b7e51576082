// `ignavctl verify`'s table: VerificationState as the paper's Table V shows targeting error (per
// target: planned, actual, error, lateral, depth, what the model predicted), then the summary and
// the fitted tissues.
#pragma once

#include "ignav/protocol/client.hpp"

namespace ignav::ctl {

void printVerification(const protocol::StateMirror& state);

}  // namespace ignav::ctl
