#include "ignav/protocol/commands.hpp"

#include "ignav/commands/command_table.hpp"

namespace ignav::protocol {

static_assert(static_cast<int>(Role::kViewer) == static_cast<int>(commands::ClientRole::kViewer) &&
                  static_cast<int>(Role::kPlanner) ==
                      static_cast<int>(commands::ClientRole::kPlanner) &&
                  static_cast<int>(Role::kApprover) ==
                      static_cast<int>(commands::ClientRole::kApprover),
              "protocol::Role and commands::ClientRole name the same roles in the same order");

std::optional<std::int32_t> commandKindFromName(const std::string& name) {
  const auto* spec = commands::commandNamed(name);
  if (!spec || spec->wire_kind == commands::kNoWireKind) return std::nullopt;
  return spec->wire_kind;
}

Role requiredRole(std::int32_t kind) {
  const auto* spec = commands::commandOfWireKind(kind);
  return spec ? static_cast<Role>(spec->role) : Role::kApprover;  // unknown kinds are refused
}

const char* commandKindName(std::int32_t kind) {
  const auto* spec = commands::commandOfWireKind(kind);
  return spec ? spec->name : "unknown";
}

}  // namespace ignav::protocol
