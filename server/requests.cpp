#include "requests.hpp"

namespace ignav::server {

using workflow::Input;
using workflow::InputKind;

std::optional<Input> toInput(const protocol::Command& c) {
  const auto* spec = workflow::commandOfWireKind(c.kind);
  if (!spec) return std::nullopt;
  Input in;
  in.kind = spec->kind;
  in.client_id = c.client_id;
  in.request_id = c.request_id;
  in.path = c.path;
  for (const auto& p : c.points)
    in.points.push_back(protocol::toEigen(p));
  in.ids = c.ids;
  // The matrix is a fixed array, always on the wire: it means something only where it is asked,
  // and where it may be left out, all zeros (never a transform) leaves it out.
  if (spec->args.matrix_is) {
    const Eigen::Matrix4d m = protocol::fromRowMajor(c.matrix);
    if (!spec->args.matrix_optional || !m.isZero(0.0)) in.matrix = m;
  }
  return in;
}

Input toInput(const protocol::Approval& a) {
  Input in;
  in.kind = InputKind::kApprove;
  in.client_id = a.client_id;
  in.request_id = a.request_id;
  in.plan_id = a.plan_id;
  in.digest = a.digest;
  return in;
}

Input toInput(const protocol::EmergencyStop& e) {
  Input in;
  in.kind = InputKind::kEmergencyStop;
  in.client_id = e.client_id;
  in.request_id = e.request_id;
  return in;
}

protocol::Reply toWire(const workflow::Reply& r) {
  return {r.client_id, r.request_id, r.accepted,      r.error_code, r.message,
          r.target_id, r.revision,   r.server_time_s, r.job};
}

}  // namespace ignav::server
