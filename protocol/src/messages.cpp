#include "ignav/protocol/wire/messages.hpp"

namespace ignav::protocol {
namespace {

std::string copy(const char* s) {
  return s ? std::string(s) : std::string();
}

}  // namespace

std::optional<workflow::Input> toInput(const ignav_msg_Command& c) {
  const auto* spec = workflow::commandOfWireKind(c.kind);
  if (!spec) return std::nullopt;
  workflow::Input in;
  in.kind = spec->kind;
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
  // The matrix is a fixed array, always on the wire: it means something only where it is asked.
  if (spec->args.matrix_is) in.matrix = fromRowMajor(c.matrix);
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
