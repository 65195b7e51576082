#include "ignav/protocol/client.hpp"

#include <thread>

#include "ignav/protocol/messages.hpp"

namespace ignav::protocol {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

std::string str(const char* s) {
  return s ? s : "";
}
json point(const ignav_msg_Point3& p) {
  return {p.x, p.y, p.z};
}
template <typename Seq>
json points(const Seq& seq) {
  json out = json::array();
  for (std::uint32_t i = 0; i < seq._length; ++i)
    out.push_back(point(seq._buffer[i]));
  return out;
}
template <std::size_t N>
json array(const double (&a)[N]) {
  return json(std::vector<double>(a, a + N));
}

}  // namespace

// A writer this identity may not have: DDS Security refuses it (PermissionDenied) when the
// permissions do not grant the topic; the refusal is kept and named when the writer is needed.
template <typename T>
struct OptionalWriter {
  OptionalWriter(const Participant& p, const dds_topic_descriptor_t* desc, const char* name)
      : topic(name) {
    try {
      writer = std::make_unique<Writer<T>>(p, desc, name, Qos::kRequest);
    } catch (const PermissionDenied&) {
      writer.reset();  // refused: named when it is needed
    }
  }
  const Writer<T>& get(const std::string& what) const {
    if (!writer) {
      throw PermissionDenied(what +
                             ": this identity's DDS Security permissions do not allow "
                             "publishing on " +
                             topic);
    }
    return *writer;
  }
  bool ready() const { return !writer || writer->matched() > 0; }
  std::string topic;
  std::unique_ptr<Writer<T>> writer;
};

struct Client::Impl {
  // Replies go to every client on the topic; a client keeps its own only (docs/RELIABILITY.md:
  // with 20 clients, waking for and copying everyone's slices took the cores).
  std::string client_id;
  Participant participant;
  OptionalWriter<ignav_msg_Command> commands[3];  // by Role
  Reader<ignav_msg_Reply> replies;
  Writer<ignav_msg_SliceRequest> slice_requests;
  Reader<ignav_msg_SliceReply> slice_replies;
  Reader<ignav_msg_WorkflowState> workflow;
  Reader<ignav_msg_RobotState> robot;
  Reader<ignav_msg_VolumeState> volume;
  Reader<ignav_msg_RegistrationState> registration;
  Reader<ignav_msg_TargetState> target;
  Reader<ignav_msg_Health> health;
  OptionalWriter<ignav_msg_Approval> approvals;
  Writer<ignav_msg_EmergencyStop> emergency_stops;
  Reader<ignav_msg_ApprovalState> approval;
  Reader<ignav_msg_MotionState> motion;
  WaitSet waitset;

  template <typename T>
  static bool mine(const void* sample, void* id) {
    const char* to = static_cast<const T*>(sample)->client_id;
    return to && *static_cast<const std::string*>(id) == to;
  }

  Impl(std::uint32_t domain, const std::string& xml, const SecurityIdentity* identity,
       std::string id)
      : client_id(std::move(id)),
        participant(domain, xml, identity),
        commands{{participant, &ignav_msg_Command_desc, topic::kCommandViewer},
                 {participant, &ignav_msg_Command_desc, topic::kCommandPlanner},
                 {participant, &ignav_msg_Command_desc, topic::kCommandApprover}},
        replies(participant, &ignav_msg_Reply_desc, topic::kReply, Qos::kRequest,
                &mine<ignav_msg_Reply>, &client_id),
        slice_requests(participant, &ignav_msg_SliceRequest_desc, topic::kSliceRequest,
                       Qos::kRequest),
        slice_replies(participant, &ignav_msg_SliceReply_desc, topic::kSliceReply, Qos::kRequest,
                      &mine<ignav_msg_SliceReply>, &client_id),
        workflow(participant, &ignav_msg_WorkflowState_desc, topic::kWorkflow, Qos::kState),
        robot(participant, &ignav_msg_RobotState_desc, topic::kRobot, Qos::kState),
        volume(participant, &ignav_msg_VolumeState_desc, topic::kVolume, Qos::kState),
        registration(participant, &ignav_msg_RegistrationState_desc, topic::kRegistration,
                     Qos::kState),
        target(participant, &ignav_msg_TargetState_desc, topic::kTarget, Qos::kState),
        health(participant, &ignav_msg_Health_desc, topic::kHealth, Qos::kState),
        approvals(participant, &ignav_msg_Approval_desc, topic::kApproval),
        emergency_stops(participant, &ignav_msg_EmergencyStop_desc, topic::kEmergencyStop,
                        Qos::kRequest),
        approval(participant, &ignav_msg_ApprovalState_desc, topic::kApprovalState, Qos::kState),
        motion(participant, &ignav_msg_MotionState_desc, topic::kMotion, Qos::kState),
        waitset(participant) {
    waitset.attach(replies.handle());
    waitset.attach(slice_replies.handle());
  }
};

Client::Client(std::uint32_t domain_id, const std::string& config_xml, std::string client_id,
               const SecurityIdentity* identity)
    : impl_(std::make_unique<Impl>(domain_id, config_xml, identity, client_id)),
      client_id_(std::move(client_id)) {
  state_["targets"] = json::object();
  // The server answers a repeated (client_id, request_id) from memory. A client id is often
  // reused by the next process (a console's name), so request ids start at the wall clock in
  // microseconds: a later process never repeats an earlier one's ids.
  next_request_ =
      static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::microseconds>(
                                     std::chrono::system_clock::now().time_since_epoch())
                                     .count());
}

Client::~Client() = default;

bool Client::waitForServer(std::chrono::milliseconds timeout) {
  const auto end = Clock::now() + timeout;
  while (Clock::now() < end) {
    // Every writer this identity has must be matched, or its first sample could be lost.
    bool writers = impl_->approvals.ready();
    for (const auto& c : impl_->commands)
      writers = writers && c.ready();
    if (writers && impl_->commands[0].writer && impl_->replies.matched() > 0 &&
        impl_->slice_requests.matched() > 0 && impl_->slice_replies.matched() > 0 &&
        impl_->emergency_stops.matched() > 0) {
      return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

workflow::Reply Client::send(const std::string& command, const CommandArgs& args,
                             std::chrono::milliseconds timeout, std::uint64_t request_id) {
  const auto kind = commandKindFromName(command);
  if (!kind) throw std::invalid_argument("unknown command '" + command + "'");
  if (request_id == 0) request_id = next_request_++;
  OwnedCommand owned;
  owned.client_id = client_id_;
  owned.path = args.path;
  for (const auto& p : args.points)
    owned.points.push_back(toMsg(p));
  owned.ids = args.ids;
  if (args.matrix) {
    for (int k = 0; k < 16; ++k)
      owned.matrix[static_cast<std::size_t>(k)] = (*args.matrix)(k / 4, k % 4);
  }
  const Role role = requiredRole(*kind);
  impl_->commands[static_cast<int>(role)]
      .get("'" + command + "' needs the " + toString(role) + " role")
      .write(owned.build(request_id, *kind));
  return awaitReply(request_id, command, timeout);
}

workflow::Reply Client::setRegistration(const Eigen::Matrix4d& image_to_robot,
                                        std::chrono::milliseconds timeout) {
  CommandArgs args;
  args.matrix = image_to_robot;
  return send("set_registration", args, timeout);
}

workflow::Reply Client::approve(std::uint64_t plan_id, const std::string& digest,
                                std::chrono::milliseconds timeout, std::uint64_t request_id) {
  if (request_id == 0) request_id = next_request_++;
  ignav_msg_Approval a{};
  a.client_id = cstr(client_id_);
  a.request_id = request_id;
  a.plan_id = plan_id;
  a.digest = cstr(digest);
  impl_->approvals.get("approving needs the approver role").write(a);
  return awaitReply(request_id, "approve", timeout);
}

workflow::Reply Client::emergencyStop(std::chrono::milliseconds timeout) {
  const std::uint64_t request_id = next_request_++;
  ignav_msg_EmergencyStop e{};
  e.client_id = cstr(client_id_);
  e.request_id = request_id;
  impl_->emergency_stops.write(e);
  return awaitReply(request_id, "emergency_stop", timeout);
}

workflow::Reply Client::awaitReply(std::uint64_t request_id, const std::string& what,
                                   std::chrono::milliseconds timeout) {
  const auto end = Clock::now() + timeout;
  // Poll for the first 2 ms before sleeping: a reply usually comes within that, and waking a
  // sleeping thread costs ~150 µs here (docs/PERFORMANCE.md).
  const auto spin_until = Clock::now() + reply_spin_;
  std::optional<workflow::Reply> mine;
  while (!mine) {
    impl_->replies.take([&](const ignav_msg_Reply& r) {
      if (str(r.client_id) == client_id_ && r.request_id == request_id) mine = fromMsg(r);
    });
    if (mine) break;
    if (Clock::now() < spin_until) {
      std::this_thread::yield();  // leave the core to DDS receive threads (2-core machines)
      continue;
    }
    const auto now = Clock::now();
    if (now >= end) {
      throw Timeout(what + " (request " + std::to_string(request_id) + "): no reply");
    }
    impl_->waitset.wait(std::chrono::duration_cast<std::chrono::milliseconds>(end - now));
  }
  return *mine;
}

SliceResult Client::slice(const SliceArgs& args, std::chrono::milliseconds timeout) {
  const std::uint64_t request_id = next_request_++;
  ignav_msg_SliceRequest req{};
  req.client_id = cstr(client_id_);
  req.request_id = request_id;
  req.view = cstr(args.view);
  req.centre_lps = toMsg(args.centre_lps);
  req.size_px = args.size_px;
  req.pixel_mm = args.pixel_mm;
  req.window = args.window;
  req.level = args.level;
  req.overlays = args.overlays;
  req.region_only = args.region_only;
  impl_->slice_requests.write(req);
  const auto end = Clock::now() + timeout;
  std::optional<SliceResult> mine;
  while (!mine) {
    impl_->slice_replies.take([&](const ignav_msg_SliceReply& r) {
      if (str(r.client_id) != client_id_ || r.request_id != request_id) return;
      SliceResult s;
      s.ok = r.ok;
      s.message = str(r.message);
      s.width = r.width;
      s.height = r.height;
      s.pixel_to_lps = fromRowMajor(r.pixel_to_lps);
      s.png.assign(r.png._buffer, r.png._buffer + r.png._length);
      mine = std::move(s);
    });
    if (mine) break;
    const auto now = Clock::now();
    if (now >= end) throw Timeout("slice: no reply");
    impl_->waitset.wait(std::chrono::duration_cast<std::chrono::milliseconds>(end - now));
  }
  return *mine;
}

std::vector<std::string> Client::poll() {
  std::vector<std::string> changed;
  auto note = [&](const char* name, std::size_t n) {
    if (n > 0) changed.emplace_back(name);
  };
  note("workflow", impl_->workflow.take([&](const ignav_msg_WorkflowState& w) {
    json allowed = json::array();
    for (std::uint32_t i = 0; i < w.allowed_commands._length; ++i) {
      allowed.push_back(str(w.allowed_commands._buffer[i]));
    }
    state_["workflow"] = {
        {"session_id", str(w.session_id)}, {"phase", str(w.phase)},
        {"allowed_commands", allowed},     {"revision", w.revision},
        {"last_event", str(w.last_event)}, {"safety_notice", str(w.safety_notice)}};
  }));
  note("robot", impl_->robot.take([&](const ignav_msg_RobotState& r) {
    state_["robot"] = {{"name", str(r.name)},
                       {"config_path", str(r.config_path)},
                       {"r_min_mm", r.r_min_mm},
                       {"r_max_mm", r.r_max_mm},
                       {"feasible_volume_cm3", r.feasible_volume_cm3},
                       {"tissue", str(r.tissue)},
                       {"feature_points_robot", points(r.feature_points_robot)}};
  }));
  note("volume", impl_->volume.take([&](const ignav_msg_VolumeState& v) {
    state_["volume"] = {{"status", str(v.status)},
                        {"source", str(v.source)},
                        {"message", str(v.message)},
                        {"dims", {v.dims[0], v.dims[1], v.dims[2]}},
                        {"spacing_mm", array(v.spacing_mm)},
                        {"ijk_to_lps", array(v.ijk_to_lps)},
                        {"hu_min", v.hu_min},
                        {"hu_max", v.hu_max},
                        {"progress", {v.progress_done, v.progress_total}}};
  }));
  note("registration", impl_->registration.take([&](const ignav_msg_RegistrationState& r) {
    json residuals = json::array();
    for (std::uint32_t i = 0; i < r.residuals_mm._length; ++i) {
      residuals.push_back(r.residuals_mm._buffer[i]);
    }
    state_["registration"] = {{"status", str(r.status)},
                              {"message", str(r.message)},
                              {"kind", str(r.kind)},
                              {"image_points", points(r.image_points)},
                              {"robot_points", points(r.robot_points)},
                              {"image_to_robot", array(r.image_to_robot)},
                              {"scale", r.scale},
                              {"fre_mm", r.fre_mm},
                              {"residuals_mm", residuals},
                              {"auto_detected", r.auto_detected}};
  }));
  note("target", impl_->target.takeWithState([&](const ignav_msg_TargetState& t, bool alive) {
    const std::string id = std::to_string(t.id);
    if (!alive) {
      state_["targets"].erase(id);
      return;
    }
    state_["targets"][id] = {
        {"id", t.id},
        {"lps", point(t.lps)},
        {"robot", point(t.robot)},
        {"registered", t.registered},
        {"reachable", t.reachable},
        {"reach", str(t.reach)},
        {"message", str(t.message)},
        {"joints", {t.theta_c_rad, t.z_c_mm, t.z_s_mm}},
        {"steps", {t.steps[0], t.steps[1], t.steps[2]}},
        {"tre_mm", t.tre_mm},
        {"tre_warning", t.tre_warning},
        {"order", t.order},
        {"predicted_deviation_mm", t.deviation_predicted ? json(t.predicted_deviation_mm) : json()},
        {"status", str(t.status)},
        {"outside_volume", t.outside_volume},
        {"path_warning", str(t.path_warning)},
        {"path_lps", points(t.path_lps)}};
  }));
  note("approval", impl_->approval.take([&](const ignav_msg_ApprovalState& a) {
    json moves = json::array();
    for (std::uint32_t i = 0; i < a.moves._length; ++i) {
      const auto& m = a.moves._buffer[i];
      moves.push_back({{"kind", str(m.kind)},
                       {"steps", {m.steps[0], m.steps[1], m.steps[2]}},
                       {"duration_s", m.duration_s}});
    }
    json approvers = json::array();
    for (std::uint32_t i = 0; i < a.approvers._length; ++i)
      approvers.push_back(str(a.approvers._buffer[i]));
    state_["approval"] = {{"status", str(a.status)},
                          {"plan_id", a.plan_id},
                          {"digest", str(a.digest)},
                          {"target_id", a.target_id},
                          {"summary", str(a.summary)},
                          {"from_steps", {a.from_steps[0], a.from_steps[1], a.from_steps[2]}},
                          {"moves", moves},
                          {"duration_s", a.duration_s},
                          {"tre_mm", a.tre_mm},
                          {"expires_in_s", a.expires_in_s},
                          {"expires_at_unix_s", a.expires_at_unix_s},
                          {"approvers", approvers}};
  }));
  note("motion", impl_->motion.take([&](const ignav_msg_MotionState& m) {
    state_["motion"] = {
        {"controller", str(m.controller)},
        {"state", str(m.state)},
        {"fault", str(m.fault)},
        {"plan_id", m.plan_id},
        {"target_id", m.target_id},
        {"move_index", m.move_index},
        {"move_count", m.move_count},
        {"move_kind", str(m.move_kind)},
        {"steps", {m.steps[0], m.steps[1], m.steps[2]}},
        {"goal_steps", {m.goal_steps[0], m.goal_steps[1], m.goal_steps[2]}},
        {"verified_steps", {m.verified_steps[0], m.verified_steps[1], m.verified_steps[2]}},
        {"joints", {m.theta_c_rad, m.z_c_mm, m.z_s_mm}},
        {"tip_robot", point(m.tip_robot)},
        {"tip_lps", m.tip_lps_valid ? point(m.tip_lps) : json()},
        {"uptime_s", m.uptime_s}};
  }));
  note("health", impl_->health.take([&](const ignav_msg_Health& h) {
    state_["health"] = {{"version", str(h.version)},
                        {"session_id", str(h.session_id)},
                        {"session_dir", str(h.session_dir)},
                        {"uptime_s", h.uptime_s},
                        {"commands_accepted", h.commands_accepted},
                        {"commands_rejected", h.commands_rejected},
                        {"journal", str(h.journal)},
                        {"igtl_clients", h.igtl_clients},
                        {"server_time_unix_s", h.server_time_unix_s}};
  }));
  return changed;
}

void Client::waitFor(const std::function<bool(const nlohmann::json&)>& done,
                     std::chrono::milliseconds timeout) {
  const auto end = Clock::now() + timeout;
  for (;;) {
    poll();
    if (done(state_)) return;
    if (Clock::now() >= end) throw Timeout("the expected state did not arrive");
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

bool Client::mayPublish(const std::string& command) const {
  if (command == "approve") return impl_->approvals.writer != nullptr;
  const auto kind = commandKindFromName(command);
  return kind && impl_->commands[static_cast<int>(requiredRole(*kind))].writer != nullptr;
}

Eigen::Matrix4d matrixFromState(const nlohmann::json& row_major) {
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i)
    m(i / 4, i % 4) = row_major.at(static_cast<std::size_t>(i));
  return m;
}

}  // namespace ignav::protocol
