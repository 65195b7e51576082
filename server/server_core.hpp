// The Server: the event thread's object. It owns the session (the only writer), the journal and
// the DDS readers, runs the event loop and steps every input through the reducer. Its methods sit
// in three files by concern:
//   server.cpp      construction, the event loop, recovery, replay;
//   step.cpp        inputs held for a reading; one input through the reducer and its effects
//                   (workflow::executeStep's order: halts, journal, session, moves, state,
//                   replies, the rest);
//   controller.cpp  the controller component: started (once the robot-id check is clear), sent
//                   commands, its events as inputs.
// What it hands to other threads: job_runner.hpp, slices.hpp,
// reports.hpp, controller_component.hpp, igtl_bridge.hpp. docs/ARCHITECTURE.md has the picture.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "clock.hpp"
#include "controller_component.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/journal/journal.hpp"
#include "ignav/protocol/security.hpp"
#include "ignav/protocol/wire/dds.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "ignav/protocol/wire/security.hpp"
#include "ignav/workflow/session.hpp"
#include "igtl_bridge.hpp"
#include "job_runner.hpp"
#include "reports.hpp"
#include "requests.hpp"
#include "server_options.hpp"
#include "service_notify.hpp"
#include "slices.hpp"
#include "state_publisher.hpp"

namespace ignav::server {

class Server {
 public:
  // Without a journal the server only replays (nothing is written).
  Server(const ServerOptions& o, std::shared_ptr<const config::Robot> robot,
         std::filesystem::path session_dir, std::optional<journal::Journal> journal);
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Serves: a new session from its start, or the one `journal_lines` recover. Returns the exit
  // code once `stop` is true (0), or at once when recovery failed (2) or another server has this
  // robot id (4). (A step never fails the server: a journal that cannot be written refuses every
  // change instead, step.cpp.)
  int run(const std::atomic<bool>& stop, const std::vector<std::string>& journal_lines);
  // Publishes a recorded session's states one record at a time, at the recorded pace divided by
  // the speed (0: at once), then keeps serving them (and slices) until stopped. It drives no
  // controller and takes no commands.
  int replay(const std::atomic<bool>& stop, const std::vector<std::string>& lines);
  // Whether run() started the controller (a server that gave way before did not).
  bool touchedController() const { return component_ != nullptr; }

 private:
  using Input = workflow::Input;
  class Sink;  // step.cpp: one step's effects (a workflow::EffectSink)

  // server.cpp
  Status recover(const std::vector<std::string>& lines);
  void serveReadOnly(Clock::time_point until, const std::atomic<bool>& stop);
  std::size_t takeCommands();
  void step(Input in);
  bool waitsForReading(const Input& in, Clock::time_point arrived) const;
  void releaseHeld();
  void refuseHeld(const char* code, const std::string& why);
  bool reservedClientId(const std::string& client_id, std::uint64_t request_id);
  std::optional<workflow::Reply> checkPath(const Input& in) const;
  Input withSender(Input in, const char* role, dds_entity_t reader, dds_instance_handle_t from);
  void publishEverything();
  Expected<workflow::LoadedCt> reloadCt(const std::string& source);
  // Another server with this robot id (robot_peers_): an error when this one is the later to
  // start (it must stop), nothing when none is there or this one is older (the other stops).
  std::optional<std::string> robotIdConflict();
  std::optional<std::string> checkRobotIdAtStart();  // replay: listens, then serves
  void startControllerWhenClear();                   // run: once the check has passed

  // step.cpp
  void stepNow(Input in);
  void replaceSession(workflow::Session&& session);
  const Reports::Snapshot& snapshot();  // the session as it is now, shared read only
  void sendReply(const workflow::Reply& r);
  void refuseUnjournaled(const Input& in, const workflow::Effects& effects);
  void crashPoint(const char* where, std::uint64_t revision) const;
  std::pair<std::size_t, std::size_t> ctLoadProgress() const {
    return jobs_.progress(workflow::JobKind::kVolumeLoad);
  }
  std::pair<std::size_t, std::size_t> placementProgress() const {
    return jobs_.progress(workflow::JobKind::kRobotPlacement);
  }
  std::pair<std::size_t, std::size_t> proposalProgress() const {
    return jobs_.progress(workflow::JobKind::kTargetProposal);
  }
  Readings readings() const {
    return {last_reading_, toString(lifecycle_), ctLoadProgress(), placementProgress(),
            proposalProgress()};
  }
  void publishMotion() { state_.publishMotion(session_, last_reading_, toString(lifecycle_)); }
  void publishHealth();

  // controller.cpp
  void startController(bool home, const std::optional<actuation::Steps>& place_at);
  ControllerReading latestReading() const;
  // Released to the component (MotorCommand::release), or refused: an abort and a fault.
  void runController(const workflow::ControllerCommand& c);
  void takeControllerEvents();
  void onReading(const ControllerReading& reading);

  ServerOptions options_;
  const std::filesystem::path session_dir_;
  const std::string controller_name_;
  std::optional<protocol::SecurityIdentity> identity_;  // DDS Security on with it
  protocol::Participant participant_;
  protocol::Reader<ignav_msg_Command> commands_[3];  // by Role
  protocol::TopicWriter<protocol::Reply> replies_;
  protocol::TopicReader<protocol::SliceRequest> slice_requests_;
  protocol::TopicReader<protocol::SceneRequest> scene_requests_;
  protocol::Reader<ignav_msg_Approval> approvals_;
  protocol::Reader<ignav_msg_EmergencyStop> emergency_stops_;
  // Every Health in this robot's partition, this server's own included: another server with the
  // same robot id shows here (robotIdConflict).
  protocol::TopicReader<protocol::Health> robot_peers_;
  const Clock::time_point participant_started_;
  const std::string host_;
  const double started_unix_s_;
  std::set<std::string> peers_warned_;  // later servers with this id (folder@host), said once
  ServiceNotifier notifier_;            // systemd: ready, watchdog, stopping
  StatePublisher state_;
  // The slices clients ask for, drawn on a thread of their own (it writes the replies).
  Slices slices_;
  std::optional<protocol::SenderIdentities> senders_;  // with DDS Security on
  std::string journal_failure_;  // why the journal cannot be written ("" = it can)
  std::set<workflow::InputKind> unjournaled_kinds_;
  actuation::ControllerStatus last_reading_;        // the component's, as last taken (or replayed)
  Lifecycle lifecycle_ = Lifecycle::kUnconfigured;  // the component's, as last taken
  std::uint64_t move_seq_ = 0;                      // the component's number of the last move sent
  std::uint64_t last_submitted_ = 0;                // ... of the last command of any kind
  struct Held {
    Input input;
    Clock::time_point arrived;
  };
  std::deque<Held> held_;  // inputs waiting for a fresh reading (step())
  // run(): the controller is not touched until no other server with this robot id has been heard
  // for robot_id_check_ms from the participant's start (controller_due_); meanwhile the inputs
  // that read or halt it are held. (Replay has no controller and steps nothing.)
  bool controllerPending() const { return !component_; }
  Clock::time_point controller_due_{};
  bool recovering_ = false;  // run() continues a session from its journal
  Clock::time_point held_since_;
  std::string last_fault_reported_;
  std::string refused_move_;  // a move runController would not send: a fault, reported next
  protocol::WaitSet waitset_;
  // The workflow's background jobs (CT loads among them), on a thread of their own (it wakes the
  // waitset).
  JobRunner jobs_;
  // The controller component (run() only; its threads wake the waitset, so it goes first).
  std::unique_ptr<ControllerComponent> component_;
  // The report and the Slicer files, on a thread of their own; drained when the server goes.
  Reports reports_;
  std::optional<journal::Journal> journal_;
  std::string crash_at_;  // IGNAV_CRASH_AT (step.cpp)
  workflow::Session session_;
  Reports::Snapshot snapshot_;  // a copy of session_ once asked for (snapshot()), until it changes
  std::pair<std::size_t, std::size_t> last_progress_{0, 0};
  std::pair<std::size_t, std::size_t> last_placement_progress_{0, 0};
  std::pair<std::size_t, std::size_t> last_proposal_progress_{0, 0};
  // The OpenIGTLink bridge (last: its thread stops before the waitset it wakes goes away).
  std::unique_ptr<IgtlBridge> igtl_;
};

}  // namespace ignav::server
