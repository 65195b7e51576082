// What discovery shows of a participant of this process: "ignavctl operator@host" (the client's
// and the discovery helpers' participants).
#pragma once

#include <string>

namespace ignav::protocol {

std::string participantName(const std::string& who);

}  // namespace ignav::protocol
