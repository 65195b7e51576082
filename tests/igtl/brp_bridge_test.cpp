// The BRP translation without sockets: the bridge and the real workflow core in a loop (the
// server's part played by a few lines here). Coordinates are checked against the closed form of
// RAS <-> LPS; results come from the core's own verdicts.
#include <gtest/gtest.h>

#include <set>

#include <Eigen/Geometry>

#include "ignav/config/robot_config.hpp"
#include "ignav/igtl/brp.hpp"
#include "ignav/workflow/reducer.hpp"
#include "ignav/workflow/reply_codes.hpp"
#include "support/phantom_ct.hpp"

namespace ignav::igtl {
namespace {

using workflow::InputKind;
using workflow::Phase;

using test::paperRobot;

// The server's part: inputs through the reducer (stamped with a robot at rest at its position),
// replies back to the bridge, states after every step; every message to the client collected.
struct Loop {
  explicit Loop(bool approval) : bridge({approval}, 1000) {
    session = workflow::newSession("t", paperRobot(), "robot.yaml");
    workflow::Input config;
    config.kind = InputKind::kConfigLoaded;
    workflow::ApprovalPolicy policy;
    policy.approvers = {kBridgeClientId};
    config.policy = policy;
    run(config);
    sent.clear();
    inputs.clear();
  }
  void run(workflow::Input in) {
    in.time_s = 1000.0;
    actuation::ControllerStatus at_rest;
    at_rest.state = actuation::ControllerState::kIdle;
    at_rest.position = session.position;
    if (workflow::needsControllerReading(in.kind)) in.controller = at_rest;
    inputs.push_back(in.kind);
    auto step = workflow::reduce(session, in);
    session = step.session;
    for (const auto& r : step.effects.replies)
      take(bridge.onReply(r, session));
    take(bridge.onState(session));
  }
  void take(BrpOutput out) {
    for (auto& m : out.messages)
      sent.push_back(m.message);
    for (auto& in : out.inputs)
      run(in);
  }
  void receive(const Message& m) { take(bridge.onMessage(7, m, session, session.position)); }
  void command(const char* phase) { receive(stringMessage("CMD_1", phase)); }

  BrpBridge bridge;
  workflow::Session session;
  std::vector<Message> sent;
  std::vector<InputKind> inputs;
};

Eigen::Matrix4d calibrationRas() {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()).matrix();
  m.topRightCorner<3, 1>() << 5, -10, -20;
  return m;
}

TEST(BrpBridge, EveryCommandIsReceiptedFirstEvenAnUnknownOne) {
  Loop loop(false);
  loop.command("FLY_AWAY");
  ASSERT_EQ(loop.sent.size(), 3u);
  EXPECT_EQ(loop.sent[0].type, "STRING");
  EXPECT_EQ(loop.sent[0].device_name, "ACK_1");
  EXPECT_EQ(loop.sent[0].text, "FLY_AWAY");
  EXPECT_EQ(loop.sent[1].device_name, "CURRENT_STATUS");
  EXPECT_EQ(loop.sent[2].status.code, 12);
  EXPECT_TRUE(loop.inputs.empty());  // nothing reached the core
}

TEST(BrpBridge, SlicersRasCalibrationBecomesAnLpsRegistration) {
  Loop loop(false);
  loop.command("CALIBRATION");
  loop.sent.clear();
  loop.receive(transformMessage("CLB_9", calibrationRas()));
  ASSERT_EQ(loop.session.phase, Phase::kPlanning);
  // p_robot = M p_ras, and p_ras = (-x, -y, z) of p_lps: checked on a point, by hand.
  const Eigen::Vector3d lps(30, -40, 55);
  const Eigen::Vector3d ras(-30, 40, 55);
  const Eigen::Vector3d expected = (calibrationRas() * ras.homogeneous()).head<3>();
  EXPECT_LT((loop.session.registration->toRobot(lps) - expected).norm(), 1e-9);
  // The echo is the received matrix; then the result; then the registration for Slicer.
  ASSERT_EQ(loop.sent.size(), 3u);
  EXPECT_EQ(loop.sent[0].device_name, "ACK_9");
  EXPECT_EQ(loop.sent[0].matrix, calibrationRas());
  EXPECT_EQ(loop.sent[1].device_name, "CALIBRATION");
  EXPECT_EQ(loop.sent[1].status.code, 1);
  EXPECT_EQ(loop.sent[2].device_name, "ImageToRobot");
  EXPECT_LT((loop.sent[2].matrix - calibrationRas()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(BrpBridge, TargetsArriveInLpsAndTheReachablePointIsTheTarget) {
  Loop loop(false);
  loop.receive(transformMessage("CLB_1", calibrationRas()));
  const Eigen::Vector3d robot_mm(-10, 15, -190);
  Eigen::Matrix4d target = Eigen::Matrix4d::Identity();
  target.topRightCorner<3, 1>() = (calibrationRas().inverse() * robot_mm.homogeneous()).head<3>();
  loop.sent.clear();
  loop.receive(transformMessage("TGT_2", target));
  ASSERT_EQ(loop.session.targets.size(), 1u);
  const Eigen::Vector3d ras = target.topRightCorner<3, 1>();
  EXPECT_EQ(loop.session.targets[0].lps_mm, Eigen::Vector3d(-ras.x(), -ras.y(), ras.z()));
  ASSERT_EQ(loop.sent.size(), 3u);
  EXPECT_EQ(loop.sent[1].device_name, "TARGET");
  EXPECT_EQ(loop.sent[1].status.code, 1);
  EXPECT_EQ(loop.sent[2].device_name, "REACHABLE_TARGET");
  EXPECT_LT((loop.sent[2].matrix.topRightCorner<3, 1>() - ras).norm(), 1e-6);
}

// Issue 26: a target outside the CT loaded here is refused over OpenIGTLink too, with the core's
// reason (the phantom's imaged box is +-51.2, +-51.2, +-70 mm LPS).
TEST(BrpBridge, ATargetOutsideTheLoadedCtIsRefusedWithTheReason) {
  Loop loop(false);
  workflow::Input load;
  load.kind = InputKind::kLoadVolume;
  load.client_id = "planner";
  load.request_id = 1;
  load.path = "phantom:";
  loop.run(load);
  workflow::Input loaded;
  loaded.kind = InputKind::kVolumeLoaded;
  loaded.job = loop.session.ct_revision;
  loaded.loaded.volume = test::phantomCtGrid(*paperRobot());
  loaded.loaded.source = "phantom:";
  loop.run(loaded);
  loop.receive(transformMessage("CLB_1", calibrationRas()));
  ASSERT_EQ(loop.session.phase, Phase::kPlanning);
  Eigen::Matrix4d target = Eigen::Matrix4d::Identity();
  target.topRightCorner<3, 1>() << 134, 114, -18;  // RAS of LPS (-134, -114, -18)
  loop.sent.clear();
  loop.receive(transformMessage("TGT_2", target));
  EXPECT_TRUE(loop.session.targets.empty());
  const auto refusal = std::find_if(loop.sent.begin(), loop.sent.end(), [](const Message& m) {
    return m.device_name == "TARGET" && m.type == "STATUS";
  });
  ASSERT_NE(refusal, loop.sent.end());
  EXPECT_EQ(refusal->status.code, static_cast<int>(StatusCode::kConfigurationError));
  EXPECT_EQ(refusal->status.error_name, "outside_volume");
  EXPECT_NE(refusal->status.status_string.find("103.9 mm outside the loaded CT"), std::string::npos)
      << refusal->status.status_string;
}

TEST(BrpBridge, MoveToTargetApprovesTheCoresPendingPlanOnlyWhenAllowed) {
  for (bool allowed : {false, true}) {
    Loop loop(allowed);
    loop.receive(transformMessage("CLB_1", calibrationRas()));
    Eigen::Matrix4d target = Eigen::Matrix4d::Identity();
    target.topRightCorner<3, 1>() =
        (calibrationRas().inverse() * Eigen::Vector4d(-10, 15, -190, 1)).head<3>();
    loop.receive(transformMessage("TGT_2", target));
    loop.inputs.clear();
    loop.sent.clear();
    loop.command("MOVE_TO_TARGET");
    if (allowed) {
      EXPECT_EQ(loop.inputs, (std::vector<InputKind>{InputKind::kLockPlan, InputKind::kApprove}));
      EXPECT_EQ(loop.session.phase, Phase::kMoving);
      EXPECT_EQ(loop.session.motions.back().approved_by, kBridgeClientId);
      // Receipt, the new workphase; the result comes on arrival.
      ASSERT_EQ(loop.sent.size(), 2u);
      EXPECT_EQ(loop.sent[1].status.status_string, "MOVE_TO_TARGET");
    } else {
      EXPECT_EQ(loop.inputs,
                (std::vector<InputKind>{InputKind::kLockPlan, InputKind::kRequestApproval}));
      EXPECT_EQ(loop.session.phase, Phase::kPlanLocked);
      ASSERT_EQ(loop.sent.size(), 3u);
      EXPECT_EQ(loop.sent[2].device_name, "MOVE_TO_TARGET");
      EXPECT_EQ(loop.sent[2].status.code, 13);
      EXPECT_EQ(loop.sent[2].status.error_name, "awaiting_approval");
    }
  }
}

TEST(BrpBridge, RejectionsBecomeTheProtocolsCodes) {
  EXPECT_EQ(statusCodeFor("wrong_phase", Phase::kEmergency), StatusCode::kPanic);
  EXPECT_EQ(statusCodeFor("wrong_phase", Phase::kManual), StatusCode::kManualMode);
  EXPECT_EQ(statusCodeFor("wrong_phase", Phase::kFault), StatusCode::kHardwareFailure);
  EXPECT_EQ(statusCodeFor("controller_unavailable", Phase::kImaging), StatusCode::kHardwareFailure);
  EXPECT_EQ(statusCodeFor("not_similarity", Phase::kImaging), StatusCode::kConfigurationError);
  EXPECT_EQ(statusCodeFor("not_registered", Phase::kImaging), StatusCode::kNotReady);
  EXPECT_EQ(statusCodeFor("empty_plan", Phase::kPlanning), StatusCode::kNotReady);
  // The 2013 revision's reference robots: configuration error for values, not ready for the rest
  // (a start-up without its controller too), a hardware failure only for a robot that failed.
  const auto r2013 = Revision::kBrp2013;
  EXPECT_EQ(statusCodeFor("wrong_phase", Phase::kManual, r2013), StatusCode::kNotReady);
  EXPECT_EQ(statusCodeFor("controller_unavailable", Phase::kImaging, r2013), StatusCode::kNotReady);
  EXPECT_EQ(statusCodeFor("unreachable", Phase::kPlanning, r2013), StatusCode::kConfigurationError);
  EXPECT_EQ(statusCodeFor("", Phase::kFault, r2013), StatusCode::kHardwareFailure);
}

// libOpenIGTLink keeps 19 characters of an error name: every reply code of the core goes out
// whole or as a short form of its own, and no two codes share a name.
TEST(BrpBridge, EveryReplyCodeFitsTheErrorNameFieldAndStaysDistinct) {
  std::set<std::string> names;
  for (const auto& spec : workflow::replyCodeTable()) {
    const std::string name = errorNameFor(spec.name);
    EXPECT_LE(name.size(), kMaxErrorName) << spec.name;
    EXPECT_FALSE(name.empty()) << spec.name;
    EXPECT_TRUE(names.insert(name).second) << spec.name << " -> " << name << " twice";
  }
  EXPECT_EQ(errorNameFor("controller_unavailable"), "no_controller");
  EXPECT_EQ(errorNameFor("wrong_phase"), "wrong_phase");
}

TEST(BrpBridge, StatusStringsGoOutAsAscii) {
  EXPECT_EQ(asciiText("\u03b8c 30\u00b0 \u00b1 0.5 mm, \u2264 2 \u00b5m"),
            "thetac 30 deg +/- 0.5 mm, <= 2 um");
  EXPECT_EQ(asciiText("caf\u00e9\u2603."), "caf??.");  // unknown signs: one '?' each
  EXPECT_EQ(asciiText("a\tb\x01"
                      "c"),
            "a\tb c");
  const auto m = statusMessage("X", StatusCode::kOk, "\u03b8 = 12\u00b0", "\u03bb");
  EXPECT_EQ(m.status.status_string, "theta = 12 deg");
  EXPECT_EQ(m.status.error_name, "lambda");
}

TEST(BrpBridge, AWorkphaseChangeNoCommandAskedForIsToldToEveryone) {
  Loop loop(false);
  loop.command("START_UP");
  loop.sent.clear();
  workflow::Input stop;
  stop.kind = InputKind::kEmergencyStop;
  stop.client_id = "operator";
  stop.request_id = 5;
  loop.run(stop);  // a DDS client's emergency stop
  ASSERT_EQ(loop.sent.size(), 1u);
  EXPECT_EQ(loop.sent[0].device_name, "CURRENT_STATUS");
  EXPECT_EQ(loop.sent[0].status.status_string, "EMERGENCY");
  EXPECT_EQ(loop.sent[0].status.code, 3);
}

TEST(BrpBridge, PointsAreTargetsAndTooManyInOneMessageAreRefusedWhole) {
  Loop loop(false);
  loop.receive(transformMessage("CLB_1", calibrationRas()));
  const Eigen::Vector3d ras =
      (calibrationRas().inverse() * Eigen::Vector4d(-10, 15, -190, 1)).head<3>();
  Message points;
  points.type = "POINT";
  points.device_name = "F";
  points.points = {{"F-1", "TARGET", ras}, {"F-2", "TARGET", ras + Eigen::Vector3d(1, 0, 0)}};
  loop.sent.clear();
  loop.receive(points);
  ASSERT_EQ(loop.session.targets.size(), 2u);
  EXPECT_EQ(loop.session.targets[0].lps_mm, Eigen::Vector3d(-ras.x(), -ras.y(), ras.z()));
  EXPECT_EQ(loop.sent.front().type, "POINT");
  EXPECT_EQ(loop.sent.front().device_name, "ACK_F");
  points.points.resize(workflow::kMaxTargets + 1, {"P", "TARGET", ras});
  loop.sent.clear();
  loop.receive(points);
  EXPECT_EQ(loop.session.targets.size(), 2u);
  ASSERT_EQ(loop.sent.size(), 2u);
  EXPECT_EQ(loop.sent[1].status.code, 10);
  EXPECT_EQ(loop.sent[1].status.error_name, "oversized");
}

}  // namespace
}  // namespace ignav::igtl
