// The values' conversions to and from the C types idlc generates (wire/messages.hpp): every field
// lands in the C member of its name (the IDL's), the composite ones where the IDL has them, and a
// value -> sample -> value round trip loses nothing.
#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "ignav/protocol/json_view.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "requests.hpp"  // server/: what the workflow takes of a request

namespace {

using namespace ignav::protocol;
using ignav::server::toInput;
using nlohmann::json;

template <typename T>
void expectWireRoundTrip(const T& value) {
  Owned<typename MsgOf<T>::type> owned;
  const T back = fromMsg(toMsg(value, owned));
  EXPECT_EQ(json(back), json(value));  // the JSON view compares every field
}

TEST(Wire, TargetFieldsLandInTheirCMembers) {
  TargetState t;
  t.id = 7;
  t.lps = {1, 2, 3};
  t.reach = "beyond_max_radius";
  t.joints = {0.25, 12.5, 3.0};
  t.steps = {1, -2, 3000000000};
  t.predicted_deviation_mm = 1.25;
  t.path_lps = {{0, 0, 0}, {4, 5, 6}};
  Owned<ignav_msg_TargetState> owned;
  const ignav_msg_TargetState& m = toMsg(t, owned);
  EXPECT_EQ(m.id, 7u);
  EXPECT_EQ(m.lps.z, 3.0);
  EXPECT_STREQ(m.reach, "beyond_max_radius");
  EXPECT_EQ(m.reach, t.reach.c_str());  // lent, not copied: the value outlives the write
  EXPECT_STREQ(m.message, "");          // never null: Cyclone would refuse to serialise it
  EXPECT_EQ(m.theta_c_rad, 0.25);
  EXPECT_EQ(m.z_c_mm, 12.5);
  EXPECT_EQ(m.z_s_mm, 3.0);
  EXPECT_EQ(m.steps[2], 3000000000);
  EXPECT_TRUE(m.deviation_predicted);
  EXPECT_EQ(m.predicted_deviation_mm, 1.25);
  ASSERT_EQ(m.path_lps._length, 2u);
  EXPECT_FALSE(m.path_lps._release);
  EXPECT_EQ(m.path_lps._buffer[1].y, 5.0);

  t.predicted_deviation_mm.reset();
  Owned<ignav_msg_TargetState> none;
  EXPECT_FALSE(toMsg(t, none).deviation_predicted);
  EXPECT_EQ(none.msg.predicted_deviation_mm, 0.0);
}

TEST(Wire, MotionTipInLpsTravelsWithItsFlag) {
  MotionState m;
  m.tip_lps = Point3{4, 5, 6};
  Owned<ignav_msg_MotionState> owned;
  EXPECT_TRUE(toMsg(m, owned).tip_lps_valid);
  EXPECT_EQ(owned.msg.tip_lps.y, 5.0);
  owned.msg.tip_lps_valid = false;
  EXPECT_FALSE(fromMsg(owned.msg).tip_lps.has_value());
}

TEST(Wire, SequencesOfStringsAndStructs) {
  ApprovalState a;
  a.moves = {{"translate_cannula", {0, 1200, 0}, 1.5}, {"deploy_stylet", {0, 0, 800}, 0.5}};
  a.approvers = {"op", "chief"};
  Owned<ignav_msg_ApprovalState> owned;
  const auto& m = toMsg(a, owned);
  ASSERT_EQ(m.moves._length, 2u);
  EXPECT_STREQ(m.moves._buffer[1].kind, "deploy_stylet");
  EXPECT_EQ(m.moves._buffer[0].steps[1], 1200);
  ASSERT_EQ(m.approvers._length, 2u);
  EXPECT_STREQ(m.approvers._buffer[1], "chief");
  EXPECT_EQ(m.from_steps[0], 0);
  EXPECT_EQ(std::string(m.status), "");
}

TEST(Wire, BytesAreLentAndCopiedBack) {
  SliceReply r;
  r.client_id = "viewer";
  r.ok = true;
  r.png = {0x89, 'P', 'N', 'G'};
  r.pixel_to_lps[15] = 1.0;
  Owned<ignav_msg_SliceReply> owned;
  const auto& m = toMsg(r, owned);
  EXPECT_EQ(m.png._buffer, r.png.data());
  EXPECT_EQ(m.pixel_to_lps[15], 1.0);
  const SliceReply back = fromMsg(m);
  EXPECT_EQ(back.png, r.png);
  EXPECT_EQ(back.client_id, "viewer");
}

TEST(Wire, AnEmptyCSampleReadsAsDefaults) {
  // Null strings and empty sequences, as a zeroed sample has them.
  const ignav_msg_WorkflowState empty{};
  const WorkflowState w = fromMsg(empty);
  EXPECT_EQ(w.phase, "");
  EXPECT_TRUE(w.allowed_commands.empty());
}

TEST(Wire, EveryTopicRoundTrips) {
  WorkflowState w;
  w.phase = "planning";
  w.allowed_commands = {"add_target", "lock_plan"};
  w.revision = 9;
  w.target_ids = {7, 3, 12};
  expectWireRoundTrip(w);
  RobotState r;
  r.name = "torabi2014";
  r.cannula_travel_mm = 90.0;
  r.stylet_travel_mm = 30.0;
  r.feature_points_robot = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
  expectWireRoundTrip(r);
  VolumeState v;
  v.status = "loading";
  v.dims = {512, 512, 200};
  v.ijk_to_lps[3] = -100.0;
  v.progress = {20, 200};
  expectWireRoundTrip(v);
  RegistrationState g;
  g.status = "registered";
  g.image_points = {{1, 1, 1}};
  g.residuals_mm = {0.1, 0.2};
  g.auto_detected = true;
  expectWireRoundTrip(g);
  TargetState t;
  t.id = 3;
  t.joints = {1, 2, 3};
  t.predicted_deviation_mm = 0.5;
  t.path_lps = {{1, 2, 3}};
  expectWireRoundTrip(t);
  ApprovalState a;
  a.moves = {{"deploy_stylet", {0, 0, 800}, 0.5}};
  a.approvers = {"op"};
  expectWireRoundTrip(a);
  MotionState m;
  m.joints = {0.5, 1, 2};
  m.tip_lps = Point3{1, 2, 3};
  expectWireRoundTrip(m);
  Health h;
  h.journal = "ok";
  h.igtl_clients = 2;
  expectWireRoundTrip(h);
  m.lifecycle = "lost";
  expectWireRoundTrip(m);
  expectWireRoundTrip(Reply{"op", 4, false, "wrong_phase", "not now", 0, 12});
  Command c;
  c.client_id = "op";
  c.request_id = 8;
  c.kind = 7;
  c.path = "/data/ct";
  c.points = {{1, 2, 3}, {4, 5, 6}};
  c.ids = {3, 1, 2};
  c.matrix[0] = c.matrix[5] = c.matrix[10] = c.matrix[15] = 1.0;
  c.matrix[3] = -12.5;
  expectWireRoundTrip(c);
  expectWireRoundTrip(Approval{"op", 5, 3, "ab12"});
  expectWireRoundTrip(EmergencyStop{"op", 6});
  SliceRequest s;
  s.view = "coronal";
  s.centre_lps = {1, 2, 3};
  s.size_px = 256;
  s.overlays = s.region_only = true;
  Owned<ignav_msg_SliceRequest> owned;
  const SliceRequest back = fromMsg(toMsg(s, owned));
  EXPECT_EQ(back.view, "coronal");
  EXPECT_EQ(back.centre_lps.z, 3.0);
  EXPECT_EQ(back.size_px, 256u);
  EXPECT_TRUE(back.region_only);
}

TEST(Wire, ApprovalsConvertToTheWorkflowsInput) {
  const Approval approval{"op", 5, 3, "ab12"};
  Owned<ignav_msg_Approval> owned;
  const auto in = toInput(fromMsg(toMsg(approval, owned)));
  EXPECT_EQ(in.kind, ignav::workflow::InputKind::kApprove);
  EXPECT_EQ(in.client_id, "op");
  EXPECT_EQ(in.plan_id, 3u);
  EXPECT_EQ(in.digest, "ab12");
}

TEST(Wire, ACommandIsReadOnlyAsFarAsItsLimit) {
  // 5000 points and ids on the wire: the server copies one past the most a command may carry.
  std::vector<ignav_msg_Point3> points(5000, ignav_msg_Point3{1, 2, 3});
  std::vector<std::uint32_t> ids(5000, 7);
  ignav_msg_Command sample{};
  std::string client = "op";
  sample.client_id = cstr(client);
  sample.kind = commandKindFromName("reorder_targets").value();
  viewSequence(sample.points, points);
  viewSequence(sample.ids, ids);
  const Command c = commandOf(sample);
  EXPECT_EQ(c.points.size(), kMaxCommandItemsRead);
  EXPECT_EQ(c.ids.size(), kMaxCommandItemsRead);
  const auto in = toInput(c);
  ASSERT_TRUE(in);
  EXPECT_EQ(in->kind, ignav::workflow::InputKind::kReorderTargets);
  EXPECT_EQ(in->ids.size(), kMaxCommandItemsRead);
}

TEST(Wire, CommandsConvertToTheWorkflowsInputByTheirDeclaredArguments) {
  Command c;
  c.client_id = "op";
  c.request_id = 3;
  c.kind = commandKindFromName("set_registration").value();
  for (int i = 0; i < 16; ++i)
    c.matrix[static_cast<std::size_t>(i)] = i;
  auto in = toInput(c);
  ASSERT_TRUE(in);
  ASSERT_TRUE(in->matrix);
  EXPECT_EQ((*in->matrix)(1, 2), 6.0);  // row-major: row 1, column 2 is element 6
  // The matrix is always on the wire; only a command that takes one gets it.
  c.kind = commandKindFromName("add_target").value();
  c.points = {{1, 2, 3}};
  in = toInput(c);
  ASSERT_TRUE(in);
  EXPECT_FALSE(in->matrix);
  EXPECT_EQ(in->points.at(0).z(), 3.0);
  // Where the matrix may be left out, all zeros (never a transform) leaves it out; a zero matrix
  // where one is required still arrives, for the reducer to refuse.
  c.points.clear();
  c.kind = commandKindFromName("load_confirmation").value();
  c.path = "/scans/confirmation";
  in = toInput(c);
  ASSERT_TRUE(in);
  ASSERT_TRUE(in->matrix);
  c.matrix = {};
  in = toInput(c);
  ASSERT_TRUE(in);
  EXPECT_FALSE(in->matrix);
  c.kind = commandKindFromName("set_registration").value();
  in = toInput(c);
  ASSERT_TRUE(in);
  EXPECT_TRUE(in->matrix);
  c.kind = 4096;  // no command has it
  EXPECT_FALSE(toInput(c));
}

}  // namespace
