// Moves as only the workflow makes them, for tests of what sends them (the controller component):
// a request of the given increments waits for approval in a session, the reducer approves it
// (its approval check is the only maker of an ApprovedMotion), and each segment is released as
// the server releases it (MotorCommand::release). Nothing here builds a move any other way.
#pragma once

#include <gtest/gtest.h>

#include <vector>

#include "controller_component.hpp"
#include "ignav/workflow/reducer.hpp"
#include "support/phantom_ct.hpp"

namespace ignav::test {

inline std::vector<server::MotorCommand> approvedMoves(
    const std::vector<actuation::Steps>& segments, const actuation::Steps& from = {}) {
  workflow::Session s = workflow::newSession("component-test", paperRobot(), "robot.yaml");
  s.phase = workflow::Phase::kPlanLocked;
  s.policy.approvers = {"surgeon"};
  workflow::MotionRequest request;
  request.plan_id = 1;
  request.target_id = 1;
  request.from = from;
  for (const auto& steps : segments) {
    planning::JointMove move;
    move.steps = steps;
    request.moves.push_back(move);
  }
  request.expires_s = 1e12;
  request.digest = workflow::requestDigest(workflow::scopeOf(s), request);
  s.pending = request;

  workflow::Input approve;
  approve.kind = workflow::InputKind::kApprove;
  approve.client_id = "surgeon";
  approve.request_id = 1;
  approve.plan_id = request.plan_id;
  approve.digest = request.digest;
  approve.controller = actuation::ControllerStatus{actuation::ControllerState::kIdle, from, {}, ""};
  const auto step = workflow::reduce(s, approve);
  std::vector<server::MotorCommand> out;
  if (step.effects.replies.empty() || !step.effects.replies[0].accepted ||
      step.effects.controller.empty() || !step.effects.controller[0].approval()) {
    ADD_FAILURE() << "the approval was refused: "
                  << (step.effects.replies.empty() ? "" : step.effects.replies[0].message);
    return out;
  }
  const auto& approved = *step.effects.controller[0].approval();
  for (std::size_t k = 0; k < segments.size(); ++k) {
    out.push_back(
        server::MotorCommand::release(workflow::ControllerCommand::move(approved, k)).value());
  }
  return out;
}

inline server::MotorCommand released(const workflow::ControllerCommand& command) {
  return server::MotorCommand::release(command).value();
}

}  // namespace ignav::test
