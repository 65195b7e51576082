#include "ignav/protocol/wire/messages.hpp"

#include <algorithm>

namespace ignav::protocol {

static_assert(kMaxCommandItemsRead == workflow::kMaxTargets + 1,
              "the server reads one item past the most a command may carry");

Command commandOf(const ignav_msg_Command& sample) {
  // A shallow copy whose sequences look shorter: nothing past the limit is copied out.
  ignav_msg_Command capped = sample;
  const auto cap = static_cast<std::uint32_t>(kMaxCommandItemsRead);
  capped.points._length = std::min(capped.points._length, cap);
  capped.ids._length = std::min(capped.ids._length, cap);
  return fromMsg(capped);
}

std::optional<workflow::Input> toInput(const Command& c) {
  const auto* spec = workflow::commandOfWireKind(c.kind);
  if (!spec) return std::nullopt;
  workflow::Input in;
  in.kind = spec->kind;
  in.client_id = c.client_id;
  in.request_id = c.request_id;
  in.path = c.path;
  for (const auto& p : c.points)
    in.points.push_back(toEigen(p));
  in.ids = c.ids;
  // The matrix is a fixed array, always on the wire: it means something only where it is asked,
  // and where it may be left out, all zeros (never a transform) leaves it out.
  if (spec->args.matrix_is) {
    const Eigen::Matrix4d m = fromRowMajor(c.matrix);
    if (!spec->args.matrix_optional || !m.isZero(0.0)) in.matrix = m;
  }
  return in;
}

workflow::Input toInput(const Approval& a) {
  workflow::Input in;
  in.kind = workflow::InputKind::kApprove;
  in.client_id = a.client_id;
  in.request_id = a.request_id;
  in.plan_id = a.plan_id;
  in.digest = a.digest;
  return in;
}

workflow::Input toInput(const EmergencyStop& e) {
  workflow::Input in;
  in.kind = workflow::InputKind::kEmergencyStop;
  in.client_id = e.client_id;
  in.request_id = e.request_id;
  return in;
}

Reply toWire(const workflow::Reply& r) {
  return {r.client_id, r.request_id, r.accepted, r.error_code, r.message, r.target_id, r.revision};
}

}  // namespace ignav::protocol
