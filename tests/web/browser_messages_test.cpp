// The gateway's translation of browser messages (docs/WEB.md): what reaches the DDS client, and
// every refusal with the field it names.
#include "browser_messages.hpp"

#include <gtest/gtest.h>

namespace ignav::web {
namespace {

using nlohmann::json;

BrowserRequest parsed(const std::string& text) {
  auto r = parseBrowserMessage(text);
  if (auto* bad = std::get_if<BadRequest>(&r)) ADD_FAILURE() << text << ": " << bad->message;
  return std::get<BrowserRequest>(r);
}

BadRequest refused(const std::string& text) {
  auto r = parseBrowserMessage(text);
  EXPECT_TRUE(std::holds_alternative<BadRequest>(r)) << text << " was accepted";
  return std::holds_alternative<BadRequest>(r) ? std::get<BadRequest>(r) : BadRequest{};
}

TEST(BrowserMessages, CommandCarriesKindPointsIdsAndPath) {
  const auto r =
      parsed(R"({"op":"command","seq":7,"kind":"move_target","points":[[1.5,-2,3e2]],"ids":[4]})");
  EXPECT_EQ(r.seq, 7u);
  const auto& c = std::get<CommandRequest>(r.body);
  EXPECT_EQ(c.kind, "move_target");
  ASSERT_EQ(c.args.points.size(), 1u);
  EXPECT_EQ(c.args.points[0], Eigen::Vector3d(1.5, -2.0, 300.0));
  EXPECT_EQ(c.args.ids, std::vector<std::uint32_t>{4});
  EXPECT_TRUE(c.args.path.empty());

  const auto load = parsed(R"({"op":"command","seq":0,"kind":"load_volume","path":"phantom:"})");
  EXPECT_EQ(std::get<CommandRequest>(load.body).args.path, "phantom:");
}

// The gateway offered set_registration to browsers but dropped its matrix (issue 39.7).
TEST(BrowserMessages, ARegistrationMatrixIsCarriedRowByRow) {
  const auto r = parsed(R"({"op":"command","seq":3,"kind":"set_registration",)"
                        R"("matrix":[0,-1,0,10, 1,0,0,-20.5, 0,0,1,300, 0,0,0,1]})");
  const auto& c = std::get<CommandRequest>(r.body);
  ASSERT_TRUE(c.args.matrix.has_value());
  Eigen::Matrix4d expected;
  expected << 0, -1, 0, 10, 1, 0, 0, -20.5, 0, 0, 1, 300, 0, 0, 0, 1;
  EXPECT_EQ(*c.args.matrix, expected);
  // A point through it as the server will take it: row by row, not column by column.
  EXPECT_EQ((*c.args.matrix * Eigen::Vector4d(1, 2, 3, 1)).head<3>(),
            Eigen::Vector3d(8, -19.5, 303));
  EXPECT_FALSE(std::get<CommandRequest>(parsed(R"({"op":"command","seq":4,"kind":"query"})").body)
                   .args.matrix.has_value());
  EXPECT_NE(refused(R"({"op":"command","seq":1,"kind":"set_registration","matrix":[1,2,3]})")
                .message.find("'matrix' must be 16 numbers"),
            std::string::npos);
  EXPECT_NE(refused(R"({"op":"command","seq":1,"kind":"set_registration",)"
                    R"("matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,"1"]})")
                .message.find("matrix[15] must be a finite number"),
            std::string::npos);
}

TEST(BrowserMessages, ApproveEmergencyStopAndSlice) {
  const auto a = parsed(R"({"op":"approve","seq":1,"plan_id":18446744073709551615,"digest":"ab"})");
  EXPECT_EQ(std::get<ApproveRequest>(a.body).plan_id, 18446744073709551615ull);
  EXPECT_EQ(std::get<ApproveRequest>(a.body).digest, "ab");

  EXPECT_TRUE(std::holds_alternative<EmergencyStopRequest>(
      parsed(R"({"op":"emergency_stop","seq":2})").body));

  const auto s =
      parsed(R"({"op":"slice","seq":3,"view":"coronal","centre_lps":[1,2,3],"size_px":256,)"
             R"("pixel_mm":0.25,"window":400,"level":40,"overlays":"region"})");
  const auto& args = std::get<SliceRequest>(s.body).args;
  EXPECT_EQ(args.view, "coronal");
  EXPECT_EQ(args.centre_lps, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(args.size_px, 256u);
  EXPECT_DOUBLE_EQ(args.pixel_mm, 0.25);
  EXPECT_DOUBLE_EQ(args.window, 400.0);
  EXPECT_DOUBLE_EQ(args.level, 40.0);
  EXPECT_TRUE(args.overlays);
  EXPECT_TRUE(args.region_only);

  const auto all = std::get<SliceRequest>(
      parsed(R"({"op":"slice","seq":4,"view":"axial","centre_lps":[0,0,0],"overlays":"all"})")
          .body);
  EXPECT_TRUE(all.args.overlays);
  EXPECT_FALSE(all.args.region_only);
  const auto none = std::get<SliceRequest>(
      parsed(R"({"op":"slice","seq":5,"view":"axial","centre_lps":[0,0,0],"overlays":"none"})")
          .body);
  EXPECT_FALSE(none.args.overlays);
}

TEST(BrowserMessages, RefusalsNameTheField) {
  struct Case {
    const char* text;
    const char* mentions;
    bool seq_known;
  };
  const Case cases[] = {
      {"not json", "not JSON", false},
      {"[1,2]", "not a JSON object", false},
      {R"({"op":"command"})", "'seq' is missing", false},
      {R"({"op":"command","seq":-1})", "'seq' must be a non-negative integer", false},
      {R"({"op":"command","seq":"7"})", "'seq' must be a non-negative integer", false},
      {R"({"seq":1})", "'op' is missing", true},
      {R"({"op":"launch","seq":1})", "'op' \"launch\" is not", true},
      {R"({"op":"command","seq":1})", "'kind' is missing", true},
      {R"({"op":"command","seq":1,"kind":"fire"})", "'kind' \"fire\" is not a command", true},
      {R"({"op":"command","seq":1,"kind":"add_target","points":[[1,2]]})",
       "points[0] must be [x, y, z]", true},
      {R"({"op":"command","seq":1,"kind":"add_target","points":[[1,"2",3]]})",
       "points[0] must hold numbers", true},
      // A number beyond double's range is not JSON to the parser (no infinity gets through).
      {R"({"op":"command","seq":1,"kind":"add_target","points":[[1,2,1e999]]})", "not JSON", false},
      {R"({"op":"command","seq":1,"kind":"add_target","points":{"x":1}})",
       "'points' must be an array", true},
      {R"({"op":"command","seq":1,"kind":"remove_target","ids":[-3]})",
       "ids[0] must be a target id", true},
      {R"({"op":"command","seq":1,"kind":"remove_target","ids":[4294967296]})",
       "ids[0] must be a target id", true},
      {R"({"op":"command","seq":1,"kind":"load_volume","path":5})", "'path' must be a string",
       true},
      {R"({"op":"approve","seq":1,"digest":"x"})", "'plan_id' is missing", true},
      {R"({"op":"approve","seq":1,"plan_id":1.5,"digest":"x"})",
       "'plan_id' must be a non-negative integer", true},
      {R"({"op":"slice","seq":1,"centre_lps":[0,0,0]})", "'view' is missing", true},
      {R"({"op":"slice","seq":1,"view":"axial"})", "'centre_lps' is missing", true},
      {R"({"op":"slice","seq":1,"view":"axial","centre_lps":[0,0,0],"size_px":4294967296})",
       "'size_px' is 4294967296, above 4294967295", true},
      {R"({"op":"slice","seq":1,"view":"axial","centre_lps":[0,0,0],"window":"wide"})",
       "'window' must be a number", true},
      {R"({"op":"slice","seq":1,"view":"axial","centre_lps":[0,0,0],"overlays":true})",
       "'overlays' must be a string", true},
      {R"({"op":"slice","seq":1,"view":"axial","centre_lps":[0,0,0],"overlays":"some"})",
       "'overlays' \"some\" is not none, region or all", true},
  };
  for (const auto& c : cases) {
    const BadRequest bad = refused(c.text);
    EXPECT_NE(bad.message.find(c.mentions), std::string::npos)
        << c.text << " -> " << bad.message << " (expected: " << c.mentions << ")";
    EXPECT_EQ(bad.seq.has_value(), c.seq_known) << c.text;
    if (c.seq_known) {
      EXPECT_EQ(bad.seq.value_or(0), 1u) << c.text;
    }
  }
}

TEST(BrowserMessages, OversizedMessagesAndSequencesAreRefused) {
  std::string points = "[";
  for (std::size_t i = 0; i <= kMaxPoints; ++i)
    points += std::string(i ? "," : "") + "[1,2,3]";
  points += "]";
  const auto too_many =
      refused(R"({"op":"command","seq":9,"kind":"set_fiducials","points":)" + points + "}");
  EXPECT_NE(too_many.message.find("129 points, above 128"), std::string::npos) << too_many.message;

  std::string ids = "[";
  for (std::size_t i = 0; i <= kMaxIds; ++i)
    ids += std::string(i ? "," : "") + std::to_string(i);
  ids += "]";
  const auto too_many_ids =
      refused(R"({"op":"command","seq":9,"kind":"reorder_targets","ids":)" + ids + "}");
  EXPECT_NE(too_many_ids.message.find("129 ids, above 128"), std::string::npos);

  const std::string huge = R"({"op":"command","seq":9,"kind":"load_volume","path":")" +
                           std::string(kMaxMessageBytes, 'a') + "\"}";
  const auto big = refused(huge);
  EXPECT_NE(big.message.find("above 1048576"), std::string::npos) << big.message;
  EXPECT_FALSE(big.seq.has_value());  // not parsed at all
}

TEST(BrowserMessages, RepliesSlicesAndErrorsForTheBrowser) {
  protocol::Reply reply;
  reply.accepted = false;
  reply.error_code = "wrong_phase";
  reply.message = "add_target is not allowed in phase imaging";
  reply.revision = 12;
  const json r = replyMessage(44, reply);
  EXPECT_EQ(r["type"], "reply");
  EXPECT_EQ(r["seq"], 44);
  EXPECT_EQ(r["accepted"], false);
  EXPECT_EQ(r["error_code"], "wrong_phase");
  EXPECT_EQ(r["message"], reply.message);
  EXPECT_EQ(r["revision"], 12);

  protocol::SliceResult slice;
  slice.ok = true;
  slice.width = 2;
  slice.height = 1;
  slice.pixel_to_lps(0, 3) = -7.5;  // row-major: index 3
  slice.png = {'f', 'o', 'o', 'b', 'a', 'r'};
  const json s = sliceMessage(5, slice);
  EXPECT_EQ(s["pixel_to_lps"].size(), 16u);
  EXPECT_EQ(s["pixel_to_lps"][3], -7.5);
  EXPECT_EQ(s["pixel_to_lps"][15], 1.0);
  EXPECT_EQ(s["png_base64"], "Zm9vYmFy");

  const json e = errorMessage(std::nullopt, "bad_request", "the message is not JSON");
  EXPECT_TRUE(e["seq"].is_null());
  EXPECT_EQ(e["code"], "bad_request");
}

// The 3D view's scene (issue 43): the request's fields, and the numbers as base64 of their
// little-endian bytes (an int16 of -2 is FE FF; a float32 of 1.0 is 00 00 80 3F).
TEST(BrowserMessages, SceneRequestsAndTheirNumbersAsLittleEndianBase64) {
  const auto volume = std::get<SceneRequest>(
      parsed(R"({"op":"scene","seq":3,"part":"volume","first_slice":64})").body);
  EXPECT_EQ(volume.part, "volume");
  EXPECT_EQ(volume.first_slice, 64u);
  EXPECT_EQ(volume.max_voxels_per_axis, 0u);
  const auto surfaces =
      std::get<SceneRequest>(parsed(R"({"op":"scene","seq":4,"part":"surfaces"})").body);
  EXPECT_EQ(surfaces.part, "surfaces");
  EXPECT_NE(refused(R"({"op":"scene","seq":5,"part":"mesh"})").message.find("'part' \"mesh\""),
            std::string::npos);
  EXPECT_NE(refused(R"({"op":"scene","seq":6})").message.find("part"), std::string::npos);
  EXPECT_NE(refused(R"({"op":"scene","seq":7,"part":"volume","first_slice":-1})")
                .message.find("first_slice"),
            std::string::npos);

  protocol::SceneReply reply;
  reply.ok = true;
  reply.part = "volume";
  reply.dims = {2, 1, 1};
  reply.voxels = {-2, 1};
  protocol::SceneSurface surface;
  surface.name = "prostate";
  surface.kind = "structure";
  surface.colour_rgb = {0.5, 0.25, 1.0};
  surface.points_lps = {1.0f};
  surface.triangles = {0x01020304u};
  reply.surfaces.push_back(surface);
  const json m = sceneMessage(9, reply);
  EXPECT_EQ(m["type"], "scene");
  EXPECT_EQ(m["seq"], 9);
  EXPECT_EQ(m["dims"], json({2, 1, 1}));
  EXPECT_EQ(m["voxels_base64"], base64({0xfe, 0xff, 0x01, 0x00}));
  EXPECT_EQ(m["surfaces"][0]["name"], "prostate");
  EXPECT_EQ(m["surfaces"][0]["colour_rgb"], json({0.5, 0.25, 1.0}));
  EXPECT_EQ(m["surfaces"][0]["points_base64"], base64({0x00, 0x00, 0x80, 0x3f}));
  EXPECT_EQ(m["surfaces"][0]["triangles_base64"], base64({0x04, 0x03, 0x02, 0x01}));
}

TEST(BrowserMessages, Base64MatchesRfc4648Vectors) {
  // RFC 4648 §10.
  const std::pair<const char*, const char*> vectors[] = {{"", ""},
                                                         {"f", "Zg=="},
                                                         {"fo", "Zm8="},
                                                         {"foo", "Zm9v"},
                                                         {"foob", "Zm9vYg=="},
                                                         {"fooba", "Zm9vYmE="},
                                                         {"foobar", "Zm9vYmFy"}};
  for (const auto& [in, out] : vectors) {
    const std::string text = in;
    EXPECT_EQ(base64(std::vector<std::uint8_t>(text.begin(), text.end())), out) << in;
  }
  EXPECT_EQ(base64({0xff, 0xfe, 0x00}), "//4A");
}

TEST(BrowserMessages, StateMessagesCarryWholeChangedTopics) {
  const json state = {{"workflow", {{"phase", "planning"}}},
                      {"targets", {{"3", {{"id", 3}}}}},
                      {"volume", {{"status", "loaded"}}}};
  const json part = stateMessage(state, {"target", "workflow"});
  EXPECT_EQ(part["type"], "state");
  EXPECT_EQ(part["state"].size(), 2u);
  EXPECT_EQ(part["state"]["targets"]["3"]["id"], 3);
  EXPECT_EQ(part["state"]["workflow"]["phase"], "planning");
  EXPECT_EQ(stateMessage(state, {})["state"], state);
}

}  // namespace
}  // namespace ignav::web
