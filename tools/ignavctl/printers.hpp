// How ignavctl prints replies and the state for a person. The printers read the mirrored values
// (StateMirror, protocol/types.hpp), not JSON by key: a field renamed in the IDL is then a compile
// error here, not an empty column. (--json prints the JSON views instead.)
#pragma once

#include <string>

#include "ignav/protocol/client.hpp"

namespace ignav::ctl {

// `round_trip_ms` (< 0: not measured) is from writing the command to taking its reply.
void printReply(const protocol::Reply& r, bool as_json, double round_trip_ms = -1.0);

void printStatus(const protocol::StateMirror& state);      // `ignavctl status`
void printTargets(const protocol::StateMirror& state);     // `ignavctl targets ls`
void printStructures(const protocol::StateMirror& state);  // `ignavctl structures ls`
void printApproval(const protocol::StateMirror& state);    // the pending request, or that none is
void printMotion(const protocol::StateMirror& state);      // `ignavctl motion`

}  // namespace ignav::ctl
