// The session journal's records (format in reducer.hpp): one JSON line per accepted input that
// changes the session, and reading them back. Internal to modules/workflow.
#pragma once

#include <string>

#include "ignav/workflow/session.hpp"

namespace ignav::workflow::detail {

// The journal line for `in`, accepted, with the session after it.
std::string journalLine(const Input& in, const Session& after);

}  // namespace ignav::workflow::detail
