// ignavctl's subcommands by group. Each adds its own to the app and, when CLI11 parsed one of
// them, sets `chosen` to its work.
#pragma once

#include <CLI/CLI.hpp>

#include <functional>
#include <utility>

#include "ignavctl.hpp"

namespace ignav::ctl {

void addDomainCommands(CLI::App& app, Action& chosen);  // robots, doctor (doctor.cpp)
void addStateViews(CLI::App& app, Action& chosen);      // status, slice, watch (state_views.cpp)
// load, fiducials, targets, set-registration, ready: the table's commands as people type them
// (table_commands.cpp)
void addAliasCommands(CLI::App& app, Action& chosen);
void addScriptRunner(CLI::App& app, Action& chosen);  // run (script.cpp)
// approval, motion, approve, emergency-stop (motion.cpp)
void addMotionCommands(CLI::App& app, Action& chosen);
void addVerify(CLI::App& app, Action& chosen);  // verify (verify.cpp)
void addReplay(CLI::App& app, Action& chosen);  // replay (replay.cpp)
// Every table command not spelled above, by its name: `add-target X,Y,Z`, `ping`
// (table_commands.cpp). Added last, so that it knows which names are taken.
void addCommandsByName(CLI::App& app, Action& chosen);

// `sub`, when parsed, runs `work` against the server.
inline void onServer(CLI::App* sub, Action& chosen, Work work) {
  sub->callback([&chosen, work = std::move(work)] { chosen.on_server = work; });
}
// The same with the work `read` makes when `sub` is parsed: what it reads from the words typed
// (refusing them with a UsageError) is read before ignavctl joins the domain.
inline void onServerReadNow(CLI::App* sub, Action& chosen, std::function<Work()> read) {
  sub->callback([&chosen, read = std::move(read)] { chosen.on_server = read(); });
}

}  // namespace ignav::ctl
