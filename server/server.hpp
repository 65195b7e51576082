// ignav-server: the DDS edge around the workflow reducer. One thread, the event thread, runs the
// event queue (commands, approvals, emergency stops, finished loads, controller events) and is
// the only writer of the session (server.cpp, server_core.hpp; a step's effects in step.cpp);
// a loader thread runs volume loads (volume_loader.hpp); a slices thread renders the slices
// clients ask for (slices.hpp); a reports thread writes the report, its slices and the Slicer
// exports (reports.hpp); the controller component (controller_component.hpp) runs the motor
// controller on threads of its own; the OpenIGTLink listener has one for its sockets
// (igtl_bridge.hpp). docs/ARCHITECTURE.md has the picture.
#pragma once

#include <atomic>

#include "server_options.hpp"

namespace ignav::server {

// Runs until `stop` becomes true; returns the exit code.
int runServer(const ServerOptions& options, const std::atomic<bool>& stop);

}  // namespace ignav::server
