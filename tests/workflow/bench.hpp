// The server's part in workflow tests: a session driven through reduce(), each step's effects run
// in the server's order (effect_order.hpp) on a SimulatedController, time and controller readings
// stamped on every input, finished moves fed back as segment_done.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "ignav/actuation/controller.hpp"
#include "ignav/config/tissue_profiles.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/workflow/effect_order.hpp"
#include "ignav/workflow/reducer.hpp"
#include "support/phantom_ct.hpp"

namespace ignav::workflow::rig {

using actuation::ControllerState;
using actuation::ControllerStatus;
using ignav::test::paperRobot;

constexpr double kSpeed = 20000.0;  // steps/s: ten times the default, so moves take ~0.5 s
constexpr double kAcceleration = 200000.0;

using test::paperRobot;

// A tissue profile with configs/tissues.yaml's needle and these slip parameters.
inline config::TissueProfile tissueProfile(const std::string& name, double lambda1,
                                           double lambda2) {
  auto profiles = config::loadTissueProfiles(IGNAV_SOURCE_DIR "/configs/tissues.yaml");
  config::TissueProfile p;
  p.name = name;
  p.needle = profiles.value().needle;
  p.tissue = {lambda1, lambda2};
  return p;
}

inline ApprovalPolicy policy() {
  ApprovalPolicy p;
  p.approvers = {"surgeon"};
  p.expiry_s = 60.0;
  p.speed_steps_s = kSpeed;
  p.acceleration_steps_s2 = kAcceleration;
  return p;
}

// Plays the server's part: stamps inputs with the time and a controller reading, runs each step's
// effects through workflow::executeStep (the server's own order: halts before anything else,
// moves after the journal), and reports a finished move as segment_done.
class Bench {
 public:
  // tissue: the session's deflection predictions (server.yaml tissue:), as config_loaded gives it.
  // robot_id, session_uuid: what the server puts in config_loaded (the digest's scope).
  explicit Bench(std::uint64_t first_request = 0,
                 std::optional<config::TissueProfile> tissue = std::nullopt,
                 std::string robot_id = "robot-1",
                 std::string session_uuid = "6f1d2c3b-4a59-4e86-9b7a-0c1d2e3f4a5b")
      : sim_(axes()), request_(first_request) {
    (void)sim_.connect();
    (void)sim_.home();
    s = newSession("bench", paperRobot(), "robot.yaml");
    Input config = internal(InputKind::kConfigLoaded);
    config.policy = policy();
    config.tissue = std::move(tissue);
    config.robot_id = std::move(robot_id);
    config.session_uuid = std::move(session_uuid);
    feed(config);
    auto load = command(InputKind::kLoadVolume);
    load.path = "phantom:";
    feed(load);
    Input loaded = internal(InputKind::kVolumeLoaded);
    loaded.job = s.ct_revision;
    loaded.loaded.volume = ignav::test::phantomCtGrid(*paperRobot());
    loaded.loaded.source = "phantom:";  // as the server names it
    feed(loaded);
    auto rp = registration::makeRobotPhantom(paperRobot()->kinematics,
                                             paperRobot()->config.registration.scan);
    feed(command(InputKind::kSetFiducials, rp.value().spec.fiducials_lps_mm));
    EXPECT_EQ(s.phase, Phase::kPlanning);
  }

  static std::array<actuation::SimulatedAxis, 3> axes() {
    std::array<actuation::SimulatedAxis, 3> a{};
    for (auto& x : a) {
      x.speed_steps_s = kSpeed;
      x.acceleration_steps_s2 = kAcceleration;
    }
    return a;
  }

  Input command(InputKind kind, std::vector<Eigen::Vector3d> points = {},
                std::vector<std::uint32_t> ids = {}, std::string client = "surgeon") {
    Input in;
    in.kind = kind;
    in.client_id = std::move(client);
    in.request_id = ++request_;
    in.points = std::move(points);
    in.ids = std::move(ids);
    return in;
  }
  static Input internal(InputKind kind) {
    Input in;
    in.kind = kind;
    return in;
  }
  Input approve(std::uint64_t plan_id, std::string digest, std::string client = "surgeon") {
    Input in = command(InputKind::kApprove, {}, {}, std::move(client));
    in.plan_id = plan_id;
    in.digest = std::move(digest);
    return in;
  }
  Input approvePending() { return approve(s.pending.value().plan_id, s.pending->digest); }

  ControllerStatus reading() {
    sim_.advanceTo(t);
    auto r = sim_.poll();
    if (r) return *r;
    ControllerStatus c;
    c.state = ControllerState::kDisconnected;
    c.fault = r.error().message;
    return c;
  }

  Step feed(Input in) {
    in.time_s = t;
    if (needsControllerReading(in.kind) && !in.controller) in.controller = reading();
    Step step = reduce(s, in);
    Sink sink(*this);
    executeStep(step, sink);  // the server's order (effect_order.hpp); step.session moved
    return step;
  }
  Reply send(Input in) {
    auto step = feed(std::move(in));
    EXPECT_EQ(step.effects.replies.size(), 1u);
    return step.effects.replies.empty() ? Reply{} : step.effects.replies.front();
  }

  // Advances time in control periods while a motion runs, feeding segment_done at each rest.
  void runMotion(double max_s = 120.0) {
    const double end = t + max_s;
    while (s.phase == Phase::kMoving && t < end) {
      advance(0.01);
    }
  }
  void advance(double dt_s) {
    t += dt_s;
    if (s.phase != Phase::kMoving) return;
    const auto r = reading();
    if (r.state != ControllerState::kMoving) feed(internal(InputKind::kSegmentDone));
  }

  std::uint32_t addRobotTarget(const kinematics::Joints& j) {
    const Eigen::Vector3d tip = paperRobot()->kinematics.forward(j).tip_mm;
    const auto r = send(command(InputKind::kAddTarget, {s.registration->toImage(tip)}));
    EXPECT_TRUE(r.accepted) << r.message;
    return r.target_id;
  }

  const Target& target(std::uint32_t id) const {
    for (const auto& x : s.targets)
      if (x.id == id) return x;
    throw std::out_of_range("no target");
  }

  actuation::SimulatedController& sim() { return sim_; }

  Session s;
  double t = 0.0;
  std::vector<std::string> journal;

 private:
  void execute(const ControllerCommand& c) {
    sim_.advanceTo(t);
    switch (c.action()) {
      case ControllerAction::kMove:
        (void)sim_.move(c.increments());
        break;
      case ControllerAction::kStop:
        (void)sim_.stop();
        break;
      case ControllerAction::kAbort:
        (void)sim_.abort();
        break;
      case ControllerAction::kHome:
        (void)sim_.home();
        break;
      case ControllerAction::kClearFault:
        (void)sim_.clearFault();
        break;
    }
  }

  // The server's part of a step with the simulation as the controller and a vector as the journal.
  struct Sink final : EffectSink {
    explicit Sink(Bench& bench) : b(bench) {}
    void halt(const ControllerCommand& c) override { b.execute(c); }
    bool journal(const std::vector<std::string>& records) override {
      b.journal.insert(b.journal.end(), records.begin(), records.end());
      return true;
    }
    void commit(Session&& session) override { b.s = std::move(session); }
    void command(const ControllerCommand& c) override { b.execute(c); }
    Bench& b;
  };

  actuation::SimulatedController sim_;
  std::uint64_t request_ = 0;
};

}  // namespace ignav::workflow::rig
