// The state topics (docs/PROTOCOL.md): WorkflowState, RobotState, VolumeState, RegistrationState,
// TargetState, ApprovalState, MotionState, VerificationState and Health, written from a Session and
// what the server knows beside it (the controller's reading, a load's progress): each as its value
// (protocol's types.hpp), which protocol converts and writes. The event thread's own: it is the
// only caller, right after a step's journal record (effect_order.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>

#include "clock.hpp"
#include "ignav/actuation/controller.hpp"
#include "ignav/protocol/types.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "ignav/volume/volume.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::server {

// What the server knows beside the session.
struct Readings {
  actuation::ControllerStatus controller;  // the latest reading taken (or replayed)
  const char* lifecycle = "unconfigured";  // the controller component's (controller_component.hpp)
  std::pair<std::size_t, std::size_t> load_progress{0, 0};       // files read, in all (loading)
  std::pair<std::size_t, std::size_t> placement_progress{0, 0};  // a robot placement's search
  std::pair<std::size_t, std::size_t> proposal_progress{0,
                                                        0};  // a target proposal's, a seed plan's
};

// What Health says beside the session.
struct HealthFacts {
  std::string journal_failure;  // "" = the journal can be written
  std::size_t igtl_clients = 0;
  std::string robot_id;
  std::string host;
  double started_unix_s = 0.0;
};

class StatePublisher {
 public:
  StatePublisher(const protocol::Participant& participant, std::string controller_name,
                 std::filesystem::path session_dir);

  // A weakened safeguard, said in WorkflowState from now on.
  void setSafetyNotice(std::string notice) { safety_notice_ = std::move(notice); }

  // The state topics a step changed.
  void publishEffects(const workflow::Session& s, const workflow::Effects& e, const Readings& r);
  // Every state topic but MotionState and Health (at start, after recovery).
  void publishEverything(const workflow::Session& s, const Readings& r);

  void publishWorkflow(const workflow::Session& s);
  void publishRobot(const workflow::Session& s);
  void publishVolume(const workflow::Session& s, std::pair<std::size_t, std::size_t> progress);
  void publishRegistration(const workflow::Session& s);
  void publishTarget(const workflow::Session& s, std::uint32_t id);
  void disposeTarget(std::uint32_t id);
  void publishApproval(const workflow::Session& s);
  void publishMotion(const workflow::Session& s, const actuation::ControllerStatus& reading,
                     const char* lifecycle);
  void publishHealth(const workflow::Session& s, const HealthFacts& facts);
  void publishVerification(const workflow::Session& s);
  // The jobs' progress from `r` (placement, proposal); the rest of `r` is not read.
  void publishStructures(const workflow::Session& s, const Readings& r);
  void publishJobOutcome(const workflow::JobOutcome& outcome);

 private:
  double uptimeS() const;

  protocol::TopicWriter<protocol::WorkflowState> workflow_;
  protocol::TopicWriter<protocol::RobotState> robot_;
  protocol::TopicWriter<protocol::VolumeState> volume_;
  protocol::TopicWriter<protocol::RegistrationState> registration_;
  protocol::TopicWriter<protocol::TargetState> target_;
  protocol::TopicWriter<protocol::Health> health_;
  protocol::TopicWriter<protocol::ApprovalState> approval_;
  protocol::TopicWriter<protocol::MotionState> motion_;
  protocol::TopicWriter<protocol::VerificationState> verification_;
  protocol::TopicWriter<protocol::StructuresState> structures_;
  protocol::TopicWriter<protocol::JobOutcome> job_outcome_;
  const std::string controller_name_;
  const std::string session_dir_;
  const Clock::time_point started_;
  std::string safety_notice_;
  // The CT's value range, computed once per volume.
  const volume::Volume* hu_range_for_ = nullptr;
  std::pair<double, double> hu_range_{0.0, 0.0};
};

}  // namespace ignav::server
