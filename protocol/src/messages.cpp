#include "ignav/protocol/messages.hpp"

namespace ignav::protocol {
namespace {

struct KindName {
  ignav_msg_CommandKind kind;
  workflow::InputKind input;
  Role role;  // the least role that may give it (docs/SECURITY.md)
};

constexpr KindName kKinds[] = {
    {ignav_msg_CMD_LOAD_VOLUME, workflow::InputKind::kLoadVolume, Role::kPlanner},
    {ignav_msg_CMD_SET_FIDUCIALS, workflow::InputKind::kSetFiducials, Role::kPlanner},
    {ignav_msg_CMD_AUTO_FIDUCIALS, workflow::InputKind::kAutoFiducials, Role::kPlanner},
    {ignav_msg_CMD_ADD_TARGET, workflow::InputKind::kAddTarget, Role::kPlanner},
    {ignav_msg_CMD_MOVE_TARGET, workflow::InputKind::kMoveTarget, Role::kPlanner},
    {ignav_msg_CMD_REMOVE_TARGET, workflow::InputKind::kRemoveTarget, Role::kPlanner},
    {ignav_msg_CMD_CLEAR_TARGETS, workflow::InputKind::kClearTargets, Role::kPlanner},
    {ignav_msg_CMD_REORDER_TARGETS, workflow::InputKind::kReorderTargets, Role::kPlanner},
    {ignav_msg_CMD_LOCK_PLAN, workflow::InputKind::kLockPlan, Role::kPlanner},
    {ignav_msg_CMD_UNLOCK_PLAN, workflow::InputKind::kUnlockPlan, Role::kPlanner},
    {ignav_msg_CMD_STOP, workflow::InputKind::kStop, Role::kPlanner},
    {ignav_msg_CMD_RESUME, workflow::InputKind::kResume, Role::kApprover},
    {ignav_msg_CMD_EMERGENCY_STOP, workflow::InputKind::kEmergencyStop, Role::kViewer},
    {ignav_msg_CMD_RESET_EMERGENCY, workflow::InputKind::kResetEmergency, Role::kApprover},
    {ignav_msg_CMD_QUERY, workflow::InputKind::kQuery, Role::kViewer},
    {ignav_msg_CMD_REQUEST_APPROVAL, workflow::InputKind::kRequestApproval, Role::kPlanner},
    {ignav_msg_CMD_HOME, workflow::InputKind::kHome, Role::kApprover},
    {ignav_msg_CMD_SET_REGISTRATION, workflow::InputKind::kSetRegistration, Role::kPlanner},
    {ignav_msg_CMD_MANUAL, workflow::InputKind::kManual, Role::kPlanner},
    {ignav_msg_CMD_CHECK_READY, workflow::InputKind::kCheckReady, Role::kViewer},
};

std::string copy(const char* s) {
  return s ? std::string(s) : std::string();
}

}  // namespace

std::optional<ignav_msg_CommandKind> commandKindFromName(const std::string& name) {
  for (const auto& k : kKinds) {
    if (name == workflow::toString(k.input)) return k.kind;
  }
  return std::nullopt;
}

Role requiredRole(std::int32_t kind) {
  for (const auto& k : kKinds) {
    if (k.kind == kind) return k.role;
  }
  return Role::kApprover;  // unknown kinds are refused anyway
}

const char* commandKindName(std::int32_t kind) {
  for (const auto& k : kKinds) {
    if (k.kind == kind) return workflow::toString(k.input);
  }
  return "unknown";
}

std::optional<workflow::Input> toInput(const ignav_msg_Command& c) {
  const KindName* found = nullptr;
  for (const auto& k : kKinds) {
    if (k.kind == c.kind) found = &k;
  }
  if (!found) return std::nullopt;
  workflow::Input in;
  in.kind = found->input;
  in.client_id = copy(c.client_id);
  in.request_id = c.request_id;
  in.path = copy(c.path);
  // Copy at most one past the limit: the reducer reports the oversize without us holding it.
  const std::size_t cap = workflow::kMaxTargets + 1;
  for (std::uint32_t i = 0; i < c.points._length && i < cap; ++i) {
    in.points.push_back(fromMsg(c.points._buffer[i]));
  }
  for (std::uint32_t i = 0; i < c.ids._length && i < cap; ++i)
    in.ids.push_back(c.ids._buffer[i]);
  if (in.kind == workflow::InputKind::kSetRegistration) {
    Eigen::Matrix4d m;
    for (int k = 0; k < 16; ++k)
      m(k / 4, k % 4) = c.matrix[k];
    in.matrix = m;
  }
  return in;
}

workflow::Input toInput(const ignav_msg_Approval& a) {
  workflow::Input in;
  in.kind = workflow::InputKind::kApprove;
  in.client_id = copy(a.client_id);
  in.request_id = a.request_id;
  in.plan_id = a.plan_id;
  in.digest = copy(a.digest);
  return in;
}

workflow::Input toInput(const ignav_msg_EmergencyStop& e) {
  workflow::Input in;
  in.kind = workflow::InputKind::kEmergencyStop;
  in.client_id = copy(e.client_id);
  in.request_id = e.request_id;
  return in;
}

const ignav_msg_Command& OwnedCommand::build(std::uint64_t request_id, std::int32_t kind) {
  msg = {};
  msg.client_id = cstr(client_id);
  msg.request_id = request_id;
  msg.kind = kind;
  msg.path = cstr(path);
  viewSequence(msg.points, points);
  viewSequence(msg.ids, ids);
  std::copy(matrix.begin(), matrix.end(), msg.matrix);
  return msg;
}

const ignav_msg_Reply& OwnedReply::build() {
  msg = {};
  msg.client_id = cstr(reply.client_id);
  msg.request_id = reply.request_id;
  msg.accepted = reply.accepted;
  msg.error_code = cstr(reply.error_code);
  msg.message = cstr(reply.message);
  msg.target_id = reply.target_id;
  msg.revision = reply.revision;
  return msg;
}

workflow::Reply fromMsg(const ignav_msg_Reply& m) {
  return {copy(m.client_id), m.request_id, m.accepted, copy(m.error_code),
          copy(m.message),   m.target_id,  m.revision};
}

}  // namespace ignav::protocol
