// Commands on the wire by name (commands/command_table.hpp declares them): the number a command
// travels as (Command.kind) and the role whose topic it travels on. No DDS here.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "ignav/protocol/topics.hpp"

namespace ignav::protocol {

// Command.kind of a command by name ("load_volume", ...; commands/command_table.hpp), for clients;
// nullopt for a name that is no command on the Command topics (approve has its own topic).
std::optional<std::int32_t> commandKindFromName(const std::string& name);
// Command.kind is an integer on the wire, so these take any value ("unknown" / approver for a
// value no command has).
const char* commandKindName(std::int32_t kind);
// The least role that may give a command: it travels on commandTopic(requiredRole(kind)).
Role requiredRole(std::int32_t kind);

}  // namespace ignav::protocol
