// Shared by the fuzzers that drive the workflow: the paper's robot, and a session registered on
// the phantom's markers and planning, where most commands mean something.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/workflow/reducer.hpp"
#include "support/phantom_ct.hpp"

namespace ignav::fuzz {

inline std::shared_ptr<const config::Robot> paperRobot() {
  static const auto r = std::make_shared<const config::Robot>(
      config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml").value());
  return r;
}

// `approvers` may release motion in it.
inline workflow::Session planningSession(std::vector<std::string> approvers) {
  using workflow::Input;
  using workflow::InputKind;
  const auto robot = paperRobot();
  workflow::Session session = workflow::newSession("fuzz", robot, "robot.yaml");
  std::uint64_t request = 0;
  auto feed = [&](Input in) {
    in.time_s = 1000.0;
    session = workflow::reduce(session, in).session;
  };
  Input config;
  config.kind = InputKind::kConfigLoaded;
  config.policy = workflow::ApprovalPolicy{};
  config.policy->approvers = std::move(approvers);
  feed(config);
  Input load;
  load.kind = InputKind::kLoadVolume;
  load.client_id = "op";
  load.request_id = ++request;
  load.path = "phantom:";
  feed(load);
  Input loaded;
  loaded.kind = InputKind::kVolumeLoaded;
  loaded.job = session.ct_revision;
  loaded.loaded.volume = test::phantomCtGrid(*robot);
  feed(loaded);
  Input fiducials;
  fiducials.kind = InputKind::kSetFiducials;
  fiducials.client_id = "op";
  fiducials.request_id = ++request;
  fiducials.points =
      registration::makeRobotPhantom(robot->kinematics, robot->config.registration.scan)
          .value()
          .spec.fiducials_lps_mm;
  feed(fiducials);
  return session;
}

}  // namespace ignav::fuzz
