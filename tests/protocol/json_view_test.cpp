// The JSON views of the topics' values, linked against ignav::protocol_types alone (no DDS, no
// workflow). The expected documents are written out by hand in the shapes browsers read
// (tools/ignav-web/app/src/state.ts) and `ignavctl status --json` prints: a view that drifts from
// them fails here before it reaches a browser.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "ignav/protocol/json_view.hpp"
#include "ignav/protocol/topics.hpp"
#include "ignav/protocol/types.hpp"

namespace {

using namespace ignav::protocol;
using nlohmann::json;

TargetState aTarget() {
  TargetState t;
  t.id = 7;
  t.lps = {1.5, -2.0, 30.25};
  t.robot = {0.5, 1.0, -120.0};
  t.registered = true;
  t.reachable = true;
  t.reach = "reachable";
  t.message = "ok";
  t.joints = {0.25, 12.5, 3.0};
  t.steps = {100, -200, 3000000000};
  t.tre_mm = 0.75;
  t.tre_warning = false;
  t.order = 2;
  t.predicted_deviation_mm = 1.25;
  t.status = "planned";
  t.outside_volume = false;
  t.path_warning = "";
  t.path_lps = {{0, 0, 0}, {1, 2, 3}};
  return t;
}

MotionState aMotion() {
  MotionState m;
  m.controller = "simulated";
  m.state = "moving";
  m.lifecycle = "active";
  m.fault = "";
  m.plan_id = 42;
  m.target_id = 7;
  m.move_index = 2;
  m.move_count = 4;
  m.move_kind = "translate_cannula";
  m.steps = {1, 2, 3};
  m.goal_steps = {4, 5, 6};
  m.verified_steps = {-1, -2, -3};
  m.joints = {0.5, 10.0, 2.0};
  m.tip_robot = {1, 2, 3};
  m.tip_lps = Point3{4, 5, 6};
  m.uptime_s = 12.5;
  m.needle_lps = {{1, 2, 3}, {1, 2, 13}, {2, 2, 20}};
  return m;
}

ApprovalState anApproval() {
  ApprovalState a;
  a.status = "pending";
  a.plan_id = 3;
  a.digest = "ab12";
  a.target_id = 7;
  a.summary = "target 7";
  a.from_steps = {0, 0, 0};
  a.moves = {{"translate_cannula", {0, 1200, 0}, 1.5}, {"deploy_stylet", {0, 0, 800}, 0.5}};
  a.duration_s = 2.0;
  a.tre_mm = 0.75;
  a.expires_in_s = 60.0;
  a.expires_at_unix_s = 1.7e9;
  a.approvers = {"op", "chief"};
  return a;
}

// Every field round-trips: value -> JSON -> value -> the same JSON.
template <typename T>
void expectRoundTrip(const T& value) {
  const json j = value;
  const T back = j.get<T>();
  EXPECT_EQ(json(back), j) << j.dump();
}

TEST(JsonView, TargetIsWhatBrowsersRead) {
  const json expected = json::parse(R"({
    "id": 7, "lps": [1.5, -2.0, 30.25], "robot": [0.5, 1.0, -120.0], "registered": true,
    "reachable": true, "reach": "reachable", "message": "ok", "joints": [0.25, 12.5, 3.0],
    "steps": [100, -200, 3000000000], "tre_mm": 0.75, "tre_warning": false, "order": 2,
    "predicted_deviation_mm": 1.25, "status": "planned", "outside_volume": false,
    "path_warning": "", "path_lps": [[0, 0, 0], [1, 2, 3]], "compensated": false,
    "aim_tissue": "", "nominal_joints": [0, 0, 0], "nominal_landing_robot": [0, 0, 0],
    "predicted_landing_robot": [0, 0, 0], "pause_z_s_mm": 0, "paused": false,
    "paused_joints": [0, 0, 0], "reaimed": false, "previous_joints": [0, 0, 0],
    "previous_landing_robot": [0, 0, 0], "reaimed_landing_robot": [0, 0, 0], "replan": "",
    "clearances": [], "clearance_refusal": "", "clearance_override": ""})");
  EXPECT_EQ(json(aTarget()), expected);
}

TEST(JsonView, MotionIsWhatBrowsersRead) {
  const json expected = json::parse(R"({
    "controller": "simulated", "state": "moving", "lifecycle": "active", "fault": "",
    "plan_id": 42, "target_id": 7,
    "move_index": 2, "move_count": 4, "move_kind": "translate_cannula", "steps": [1, 2, 3],
    "goal_steps": [4, 5, 6], "verified_steps": [-1, -2, -3], "joints": [0.5, 10.0, 2.0],
    "tip_robot": [1, 2, 3], "tip_lps": [4, 5, 6], "uptime_s": 12.5,
    "needle_lps": [[1, 2, 3], [1, 2, 13], [2, 2, 20]]})");
  EXPECT_EQ(json(aMotion()), expected);
}

TEST(JsonView, AbsentOptionalsAreNull) {
  MotionState m = aMotion();
  m.tip_lps.reset();  // no registration
  EXPECT_TRUE(json(m).at("tip_lps").is_null());
  TargetState t = aTarget();
  t.predicted_deviation_mm.reset();  // no tissue profile
  EXPECT_TRUE(json(t).at("predicted_deviation_mm").is_null());
  expectRoundTrip(m);
  expectRoundTrip(t);
}

TEST(JsonView, ApprovalIsWhatBrowsersRead) {
  const json expected = json::parse(R"({
    "status": "pending", "plan_id": 3, "digest": "ab12", "target_id": 7, "summary": "target 7",
    "from_steps": [0, 0, 0],
    "moves": [{"kind": "translate_cannula", "steps": [0, 1200, 0], "duration_s": 1.5},
              {"kind": "deploy_stylet", "steps": [0, 0, 800], "duration_s": 0.5}],
    "duration_s": 2.0, "tre_mm": 0.75, "expires_in_s": 60.0, "expires_at_unix_s": 1.7e9,
    "approvers": ["op", "chief"]})");
  EXPECT_EQ(json(anApproval()), expected);
}

TEST(JsonView, VolumeProgressIsAPair) {
  VolumeState v;
  v.status = "loading";
  v.dims = {512, 512, 200};
  v.spacing_mm = {0.5, 0.5, 1.0};
  v.ijk_to_lps[0] = v.ijk_to_lps[5] = v.ijk_to_lps[10] = v.ijk_to_lps[15] = 1.0;
  v.progress = {20, 200};
  const json j = v;
  EXPECT_EQ(j.at("progress"), json::parse("[20, 200]"));
  EXPECT_EQ(j.at("dims"), json::parse("[512, 512, 200]"));
  EXPECT_EQ(j.at("ijk_to_lps").size(), 16u);
  EXPECT_EQ(j.at("ijk_to_lps")[5], 1.0);
  for (const char* name : {"status", "source", "message", "spacing_mm", "hu_min", "hu_max"})
    EXPECT_TRUE(j.contains(name)) << name;
  EXPECT_EQ(j.size(), 9u);
  expectRoundTrip(v);
}

TEST(JsonView, EveryStateTopicHasTheFieldsTheAppNames) {
  // state.ts's interfaces, field by field.
  const auto keys = [](const json& j) {
    std::vector<std::string> out;
    for (const auto& [k, v] : j.items())
      out.push_back(k);
    return out;
  };
  using Names = std::vector<std::string>;
  EXPECT_EQ(keys(json(WorkflowState{})),
            (Names{"allowed_commands", "last_event", "phase", "revision", "safety_notice",
                   "session_id", "target_ids"}));
  // cannula_travel_mm and stylet_travel_mm: on the wire all along, in the view since the field
  // lists (the app does not read them).
  EXPECT_EQ(
      keys(json(RobotState{})),
      (Names{"cannula_travel_mm", "config_path", "feasible_volume_cm3", "feature_points_robot",
             "name", "r_max_mm", "r_min_mm", "stylet_travel_mm", "tissue"}));
  EXPECT_EQ(keys(json(RegistrationState{})),
            (Names{"auto_detected", "fre_mm", "image_points", "image_to_robot", "kind", "message",
                   "residuals_mm", "robot_points", "scale", "status"}));
  EXPECT_EQ(keys(json(Health{})),
            (Names{"commands_accepted", "commands_rejected", "host", "igtl_clients", "journal",
                   "robot_id", "server_time_unix_s", "session_dir", "session_id", "started_unix_s",
                   "uptime_s", "version"}));
}

TEST(JsonView, EveryTopicRoundTrips) {
  WorkflowState w;
  w.session_id = "s1";
  w.phase = "planning";
  w.allowed_commands = {"add_target", "lock_plan"};
  w.revision = 9;
  w.last_event = "target 7 added";
  w.safety_notice = "approval over OpenIGTLink";
  w.target_ids = {7, 3, 12};
  expectRoundTrip(w);
  RobotState r;
  r.name = "torabi2014";
  r.r_min_mm = 3.0;
  r.r_max_mm = 26.5;
  r.cannula_travel_mm = 90.0;
  r.feature_points_robot = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
  r.tissue = "prostate (λ1 1, λ2 2)";
  expectRoundTrip(r);
  RegistrationState g;
  g.status = "registered";
  g.image_points = {{1, 1, 1}};
  g.robot_points = {{2, 2, 2}};
  g.image_to_robot[3] = -4.5;
  g.residuals_mm = {0.1, 0.2, 0.3};
  g.auto_detected = true;
  expectRoundTrip(g);
  expectRoundTrip(aTarget());
  expectRoundTrip(anApproval());
  expectRoundTrip(aMotion());
  Health h;
  h.version = "0.1.0";
  h.commands_accepted = 12;
  h.igtl_clients = 1;
  h.server_time_unix_s = 1.7e9;
  expectRoundTrip(h);
  expectRoundTrip(Approval{"op", 5, 3, "ab12"});
  expectRoundTrip(EmergencyStop{"op", 6});
}

TEST(JsonView, AMissingFieldKeepsItsDefaultAndAWrongOneThrows) {
  // A server older than a field (e.g. before path_lps) leaves it out.
  json j = aTarget();
  j.erase("path_lps");
  EXPECT_TRUE(j.get<TargetState>().path_lps.empty());
  j["order"] = "first";
  EXPECT_THROW(j.get<TargetState>(), json::type_error);
  EXPECT_THROW(json::parse(R"({"moves": 3})").get<ApprovalState>(), json::type_error);
}

TEST(Topics, NamesAndRoles) {
  EXPECT_STREQ(TopicOf<TargetState>::name, "ignav/state/target");
  EXPECT_EQ(TopicOf<TargetState>::qos, Qos::kState);
  EXPECT_EQ(TopicOf<Approval>::qos, Qos::kRequest);
  EXPECT_STREQ(commandTopic(Role::kPlanner), "ignav/command/planner");
  EXPECT_STREQ(toString(Role::kApprover), "approver");
}

}  // namespace
