// What the workflow takes from each request on the wire, and its reply as it travels: the
// server's side of the protocol (clients never see workflow::Input).
#pragma once

#include <optional>

#include "ignav/protocol/types.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::server {

// nullopt for a command kind that is not one of ours.
std::optional<workflow::Input> toInput(const protocol::Command& command);
workflow::Input toInput(const protocol::Approval& approval);
workflow::Input toInput(const protocol::EmergencyStop& stop);

// The reducer's reply (workflow/session.hpp) as it travels.
protocol::Reply toWire(const workflow::Reply& reply);

}  // namespace ignav::server
