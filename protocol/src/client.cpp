#include "ignav/protocol/client.hpp"

#include <map>
#include <stdexcept>
#include <thread>

#include "ignav/protocol/json_view.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "participant_name.hpp"

namespace ignav::protocol {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

std::string str(const char* s) {
  return s ? s : "";
}

// Drains a state topic's reader into `kept` and its JSON view into `state[key]`; returns how many
// were taken.
template <typename T>
std::size_t drainInto(const TopicReader<T>& reader, std::optional<T>& kept, json& state,
                      const char* key) {
  return reader.take([&](const T& value) {
    state[key] = value;
    kept = value;
  });
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
  TopicWriter<SliceRequest> slice_requests;
  TopicReader<SliceReply> slice_replies;
  TopicWriter<SceneRequest> scene_requests;
  TopicReader<SceneReply> scene_replies;
  TopicReader<WorkflowState> workflow;
  TopicReader<RobotState> robot;
  TopicReader<VolumeState> volume;
  TopicReader<RegistrationState> registration;
  TopicReader<TargetState> target;
  TopicReader<Health> health;
  OptionalWriter<ignav_msg_Approval> approvals;
  TopicWriter<EmergencyStop> emergency_stops;
  TopicReader<ApprovalState> approval;
  TopicReader<MotionState> motion;
  TopicReader<VerificationState> verification;
  TopicReader<StructuresState> structures;
  TopicReader<JobOutcome> job_outcomes;
  std::map<std::uint64_t, JobOutcome> outcomes_seen;  // by job, the newest 64
  WaitSet waitset;                                    // replies to commands
  WaitSet views_waitset;  // slices and scenes: waited on by another thread than commands

  template <typename T>
  static bool mine(const void* sample, void* id) {
    const char* to = static_cast<const T*>(sample)->client_id;
    return to && *static_cast<const std::string*>(id) == to;
  }

  Impl(std::uint32_t domain, const std::string& xml, const SecurityIdentity* identity,
       std::string id, const std::string& robot_id)
      : client_id(std::move(id)),
        participant(domain, xml, identity, robot_id, participantName(client_id)),
        commands{{participant, &ignav_msg_Command_desc, topic::kCommandViewer},
                 {participant, &ignav_msg_Command_desc, topic::kCommandPlanner},
                 {participant, &ignav_msg_Command_desc, topic::kCommandApprover}},
        replies(participant, &ignav_msg_Reply_desc, topic::kReply, Qos::kRequest,
                &mine<ignav_msg_Reply>, &client_id),
        slice_requests(participant),
        slice_replies(participant, &mine<ignav_msg_SliceReply>, &client_id),
        scene_requests(participant),
        scene_replies(participant, &mine<ignav_msg_SceneReply>, &client_id),
        workflow(participant),
        robot(participant),
        volume(participant),
        registration(participant),
        target(participant),
        health(participant),
        approvals(participant, &ignav_msg_Approval_desc, topic::kApproval),
        emergency_stops(participant),
        approval(participant),
        motion(participant),
        verification(participant),
        structures(participant),
        job_outcomes(participant),
        waitset(participant),
        views_waitset(participant) {
    waitset.attach(replies.handle());
    views_waitset.attach(slice_replies.handle());
    views_waitset.attach(scene_replies.handle());
  }
};

namespace {

// The robot is named in a refusal: an identity scoped to other robots is refused every topic.
template <typename Impl>
std::unique_ptr<Impl> makeImpl(std::uint32_t domain_id, const std::string& config_xml,
                               const SecurityIdentity* identity, const std::string& client_id,
                               const std::string& robot_id) {
  try {
    return std::make_unique<Impl>(domain_id, config_xml, identity, client_id, robot_id);
  } catch (const PermissionDenied& e) {
    throw PermissionDenied(std::string(e.what()) + " for robot '" + robot_id +
                           "' (is this identity scoped to another robot?)");
  }
}

}  // namespace

Client::Client(std::uint32_t domain_id, const std::string& config_xml, std::string client_id,
               const SecurityIdentity* identity, const std::string& robot_id)
    : impl_(makeImpl<Impl>(domain_id, config_xml, identity, client_id, robot_id)),
      domain_id_(domain_id),
      config_xml_(config_xml),
      identity_(identity ? std::optional<SecurityIdentity>(*identity) : std::nullopt),
      robot_id_(robot_id),
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

bool Client::serverMatched() const {
  // Every writer this identity has must be matched, or its first sample could be lost.
  bool writers = impl_->approvals.ready();
  for (const auto& c : impl_->commands)
    writers = writers && c.ready();
  return writers && impl_->commands[0].writer && impl_->replies.matched() > 0 &&
         impl_->slice_requests.matched() > 0 && impl_->slice_replies.matched() > 0 &&
         impl_->emergency_stops.matched() > 0;
}

void Client::makeParticipantAnew() {
  impl_.reset();  // the old participant leaves first: its peers forget its handshake
  impl_ = makeImpl<Impl>(domain_id_, config_xml_, identity_ ? &*identity_ : nullptr, client_id_,
                         robot_id_);
  ++participants_made_;
  state_ = json::object();
  state_["targets"] = json::object();
  mirror_ = StateMirror{};
}

bool Client::waitForServer(std::chrono::milliseconds timeout) {
  using std::chrono::milliseconds;
  const auto end = Clock::now() + timeout;
  // Loopback discovery takes ~10 ms and a handshake a few round trips: 3 s is ample on a clean
  // network, and on one with 50 ms of delay and 5 % loss a handshake that has not ended by then
  // has usually lost a message. Made anew after 3, 6, 12, 24, 30, 30 ... s.
  RemakeSchedule schedule(milliseconds(3000), milliseconds(30000));
  while (Clock::now() < end) {
    if (serverMatched()) return true;
    if (identity_ && schedule.due() && end - Clock::now() > milliseconds(1000)) {
      makeParticipantAnew();
      schedule.remade();
    }
    std::this_thread::sleep_for(milliseconds(5));
  }
  return false;
}

Reply Client::send(const std::string& command, const CommandArgs& args,
                   std::chrono::milliseconds timeout, std::uint64_t request_id) {
  const auto kind = commandKindFromName(command);
  if (!kind) throw std::invalid_argument("unknown command '" + command + "'");
  if (request_id == 0) request_id = next_request_++;
  Command c;
  c.client_id = client_id_;
  c.request_id = request_id;
  c.kind = *kind;
  c.path = args.path;
  c.points = toPoints3(args.points);
  c.ids = args.ids;
  if (args.matrix) c.matrix = toRowMajor(*args.matrix);
  const Role role = requiredRole(*kind);
  Owned<ignav_msg_Command> owned;
  impl_->commands[static_cast<int>(role)]
      .get("'" + command + "' needs the " + toString(role) + " role")
      .write(toMsg(c, owned));
  return awaitReply(request_id, command, timeout);
}

Reply Client::setRegistration(const Eigen::Matrix4d& image_to_robot,
                              std::chrono::milliseconds timeout) {
  CommandArgs args;
  args.matrix = image_to_robot;
  return send("set_registration", args, timeout);
}

Reply Client::approve(std::uint64_t plan_id, const std::string& digest,
                      std::chrono::milliseconds timeout, std::uint64_t request_id) {
  if (request_id == 0) request_id = next_request_++;
  const Approval approval{client_id_, request_id, plan_id, digest};
  Owned<ignav_msg_Approval> owned;
  impl_->approvals.get("approving needs the approver role").write(toMsg(approval, owned));
  return awaitReply(request_id, "approve", timeout);
}

Reply Client::emergencyStop(std::chrono::milliseconds timeout) {
  const std::uint64_t request_id = next_request_++;
  impl_->emergency_stops.write(EmergencyStop{client_id_, request_id});
  return awaitReply(request_id, "emergency_stop", timeout);
}

Reply Client::awaitReply(std::uint64_t request_id, const std::string& what,
                         std::chrono::milliseconds timeout) {
  const auto end = Clock::now() + timeout;
  // Poll for the first 2 ms before sleeping: a reply usually comes within that, and waking a
  // sleeping thread costs ~150 µs here (docs/PERFORMANCE.md).
  const auto spin_until = Clock::now() + reply_spin_;
  std::optional<Reply> mine;
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
  SliceRequest req;
  req.client_id = client_id_;
  req.request_id = request_id;
  req.view = args.view;
  req.centre_lps = toPoint3(args.centre_lps);
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
    impl_->slice_replies.take([&](const SliceReply& r) {
      if (r.client_id != client_id_ || r.request_id != request_id) return;
      SliceResult s;
      s.ok = r.ok;
      s.message = r.message;
      s.width = r.width;
      s.height = r.height;
      s.pixel_to_lps = fromRowMajor(r.pixel_to_lps);
      s.png = r.png;
      mine = std::move(s);
    });
    if (mine) break;
    const auto now = Clock::now();
    if (now >= end) throw Timeout("slice: no reply");
    impl_->views_waitset.wait(std::chrono::duration_cast<std::chrono::milliseconds>(end - now));
  }
  return *mine;
}

SceneReply Client::scene(const std::string& part, std::uint32_t first_slice,
                         std::uint32_t max_voxels_per_axis, std::chrono::milliseconds timeout) {
  SceneRequest req;
  req.client_id = client_id_;
  req.request_id = next_request_++;
  req.part = part;
  req.first_slice = first_slice;
  req.max_voxels_per_axis = max_voxels_per_axis;
  impl_->scene_requests.write(req);
  const auto end = Clock::now() + timeout;
  std::optional<SceneReply> mine;
  while (!mine) {
    impl_->scene_replies.take([&](const SceneReply& r) {
      if (r.client_id == client_id_ && r.request_id == req.request_id) mine = r;
    });
    if (mine) break;
    const auto now = Clock::now();
    if (now >= end) throw Timeout("scene " + part + ": no reply");
    impl_->views_waitset.wait(std::chrono::duration_cast<std::chrono::milliseconds>(end - now));
  }
  return *mine;
}

std::vector<std::string> Client::poll() {
  std::vector<std::string> changed;
  auto note = [&](const char* name, std::size_t n) {
    if (n > 0) changed.emplace_back(name);
  };
  // Each topic's JSON view (json_view.hpp); targets as a map by id, a disposed one removed.
  note("workflow", drainInto(impl_->workflow, mirror_.workflow, state_, "workflow"));
  note("robot", drainInto(impl_->robot, mirror_.robot, state_, "robot"));
  note("volume", drainInto(impl_->volume, mirror_.volume, state_, "volume"));
  note("registration",
       drainInto(impl_->registration, mirror_.registration, state_, "registration"));
  note("target", impl_->target.takeWithState(
                     [&](const TargetState& t) {
                       state_["targets"][std::to_string(t.id)] = t;
                       mirror_.targets[t.id] = t;
                     },
                     [&](const ignav_msg_TargetState& gone) {
                       state_["targets"].erase(std::to_string(gone.id));
                       mirror_.targets.erase(gone.id);
                     }));
  note("approval", drainInto(impl_->approval, mirror_.approval, state_, "approval"));
  note("motion", drainInto(impl_->motion, mirror_.motion, state_, "motion"));
  note("health", drainInto(impl_->health, mirror_.health, state_, "health"));
  note("verification",
       drainInto(impl_->verification, mirror_.verification, state_, "verification"));
  note("structures", drainInto(impl_->structures, mirror_.structures, state_, "structures"));
  return changed;
}

void Client::waitFor(const std::function<bool(const nlohmann::json&)>& done,
                     std::chrono::milliseconds timeout) {
  waitUntil([&](const StateMirror&) { return done(state_); }, timeout);
}

void Client::waitUntil(const std::function<bool(const StateMirror&)>& done,
                       std::chrono::milliseconds timeout) {
  const auto end = Clock::now() + timeout;
  for (;;) {
    poll();
    if (done(mirror_)) return;
    if (Clock::now() >= end) throw Timeout("the expected state did not arrive");
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

std::vector<std::string> Client::missingState() const {
  const StateMirror& m = mirror_;
  std::vector<std::string> missing;
  const std::pair<bool, const char*> topics[] = {
      {m.workflow.has_value(), "workflow"},    {m.robot.has_value(), "robot"},
      {m.volume.has_value(), "volume"},        {m.registration.has_value(), "registration"},
      {m.approval.has_value(), "approval"},    {m.motion.has_value(), "motion"},
      {m.health.has_value(), "health"},        {m.verification.has_value(), "verification"},
      {m.structures.has_value(), "structures"}};
  for (const auto& [held, name] : topics)
    if (!held) missing.emplace_back(name);
  if (m.workflow) {
    for (const auto id : m.workflow->target_ids)
      if (m.targets.count(id) == 0) missing.push_back("target " + std::to_string(id));
  }
  return missing;
}

std::vector<JobOutcome> Client::takeJobOutcomes() {
  constexpr std::size_t kKept = 64;
  auto& seen = impl_->outcomes_seen;
  std::vector<JobOutcome> arrived;
  impl_->job_outcomes.take([&](const JobOutcome& o) {
    seen[o.job] = o;
    while (seen.size() > kKept)
      seen.erase(seen.begin());
    arrived.push_back(o);
  });
  return arrived;
}

JobOutcome Client::waitForJobOutcome(std::uint64_t job, std::chrono::milliseconds timeout) {
  const auto end = Clock::now() + timeout;
  const auto& seen = impl_->outcomes_seen;
  for (;;) {
    takeJobOutcomes();
    if (auto it = seen.find(job); it != seen.end()) return it->second;
    if (Clock::now() >= end) {
      throw Timeout("no outcome of job #" + std::to_string(job) + " within " +
                    std::to_string(timeout.count()) + " ms");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

bool Client::waitForPresent(std::chrono::milliseconds timeout) {
  try {
    waitUntil([this](const StateMirror&) { return missingState().empty(); }, timeout);
    return true;
  } catch (const Timeout&) {
    return false;
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
