#include "ignav/protocol/commands.hpp"

#include "ignav/workflow/inputs.hpp"

namespace ignav::protocol {

static_assert(static_cast<int>(Role::kViewer) == static_cast<int>(workflow::ClientRole::kViewer) &&
                  static_cast<int>(Role::kPlanner) ==
                      static_cast<int>(workflow::ClientRole::kPlanner) &&
                  static_cast<int>(Role::kApprover) ==
                      static_cast<int>(workflow::ClientRole::kApprover),
              "protocol::Role and workflow::ClientRole name the same roles in the same order");

std::optional<std::int32_t> commandKindFromName(const std::string& name) {
  const auto* spec = workflow::commandNamed(name);
  if (!spec || spec->wire_kind == workflow::kNoWireKind) return std::nullopt;
  return spec->wire_kind;
}

Role requiredRole(std::int32_t kind) {
  const auto* spec = workflow::commandOfWireKind(kind);
  return spec ? static_cast<Role>(spec->role) : Role::kApprover;  // unknown kinds are refused
}

const char* commandKindName(std::int32_t kind) {
  const auto* spec = workflow::commandOfWireKind(kind);
  return spec ? spec->name : "unknown";
}

}  // namespace ignav::protocol
