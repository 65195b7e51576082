// The words a person types, read as a command's arguments by the command's row in the table
// (commands/command_table.hpp). Every spelling of a command reads them so: its own name
// (`add-target X,Y,Z`) and its aliases (`targets add X,Y,Z`), so that a change to a row's
// arguments reaches all of them.
#pragma once

#include <Eigen/Core>

#include <string>
#include <vector>

#include "ignav/commands/command_table.hpp"
#include "ignav/protocol/client.hpp"

namespace ignav::ctl {

Eigen::Vector3d triple(const std::string& text);    // "X,Y,Z"; throws UsageError
Eigen::Matrix4d matrix16(const std::string& text);  // "m00,m01,...,m33", row-major

// `words` as the arguments of `spec`'s command, in usageOf()'s order: the path, then the ids, the
// points, the matrix. `typed` is what named the command ("add-target", "targets add"), for the
// usage a UsageError shows.
protocol::CommandArgs commandArgs(const commands::InputSpec& spec,
                                  const std::vector<std::string>& words, const std::string& typed);

// An alias of a table command, found by the words typed: its row, and what it carries.
struct AliasCall {
  const commands::InputSpec& row;
  protocol::CommandArgs args;
};
// The alias `group` ("load") or `group words[0]` ("targets add"), and the words after it read by
// its row. Throws UsageError: when no alias is so, with `usage` (the group's), or when the words
// do not fit the row, with the row's.
AliasCall aliasCall(const std::string& group, const std::vector<std::string>& words,
                    const std::string& usage);
// The aliases of `group` for a person: "add X,Y,Z | rm ID | clear | lock | unlock".
std::string aliasUsage(const std::string& group);

}  // namespace ignav::ctl
