// OpenIGTLink protocol 3 against a real ignav-server on loopback, from the tests' own version-3
// peer (v3_peer.hpp: written from the protocol's description, libOpenIGTLink's CRC). What the
// upstream OpenIGTLink 3.1 client was cut off for (issue 44) — a STRING command, a CLB_ transform
// and a COMMAND with version-2 headers and metadata — is answered in version 2, and every answer
// is checked byte by byte: header, extended header, metadata, CRC. DDS domains 177-179, 186, 189,
// 190.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "e2e/server_process.hpp"
#include "ignav/volume/dicom.hpp"
#include "ignav/volume/image_io.hpp"
#include "v3_peer.hpp"

namespace ignav::igtl3_test {
namespace {

using e2e::ServerProcess;
using nlohmann::json;
using namespace std::chrono_literals;

double nowS() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// Every version-2 frame the server sends: its parts add up, its CRC is right, its extended header
// is the 12 bytes of the description, and rebuilt by the peer's own code from the fields read it
// is the very bytes received.
void expectWellFramed(const Frame& f) {
  ASSERT_EQ(f.version, 2) << f.type << " " << f.device;
  EXPECT_TRUE(f.crc_ok) << f.type << " " << f.device;
  EXPECT_TRUE(f.sizes_ok) << f.type << " " << f.device;
  EXPECT_EQ(f.extended_header_size, 12);
  EXPECT_EQ(frame(2, f.type, f.device, f.timestamp, body2(f.content, f.message_id, f.meta)), f.raw)
      << f.type << " " << f.device;
  // Stamped with the server's clock (the same machine's): within a few seconds of ours.
  const double stamped = static_cast<double>(f.timestamp >> 32) +
                         static_cast<double>(f.timestamp & 0xffffffffULL) / 4294967296.0;
  EXPECT_LT(std::abs(stamped - nowS()), 30.0) << f.type << " " << f.device;
}

std::string attribute(const std::string& xml, const std::string& name) {
  const auto at = xml.find(" " + name + "=\"");
  if (at == std::string::npos) return "<none>";
  const auto from = at + name.size() + 3;
  return xml.substr(from, xml.find('"', from) - from);
}

const Frame* findFrame(const std::vector<Frame>& frames, const std::string& type,
                       const std::string& device) {
  for (const auto& f : frames)
    if (f.type == type && f.device == device) return &f;
  return nullptr;
}

// Slicer's calibration as the BRP tests give it: RAS -> robot, 30° about S and a shift.
void calibrationPose(float m[3][4]) {
  const float c = std::cos(static_cast<float>(M_PI / 6)),
              s = std::sin(static_cast<float>(M_PI / 6));
  const float pose[3][4] = {{c, -s, 0, 12.5f}, {s, c, 0, -20.0f}, {0, 0, 1, -40.0f}};
  std::memcpy(m, pose, sizeof pose);
}

TEST(Igtl3E2E, Version2MessagesAndCommandsAreAnsweredInVersion2ByteForByte) {
  ServerProcess server(177, {"--igtl-allow-approval"});
  Peer peer(server.igtlPort());
  ASSERT_TRUE(peer.connected());
  // Before it has spoken, a client is greeted in version 1 (every OpenIGTLink reader reads it).
  auto greeting = peer.next();
  ASSERT_TRUE(greeting.has_value());
  EXPECT_EQ(greeting->version, 1);
  EXPECT_TRUE(greeting->crc_ok);
  EXPECT_EQ(greeting->device, "CURRENT_STATUS");

  // 1. STRING CMD_0001 START_UP with a version-2 header and metadata, as OpenIGTLink 3.1 sends.
  peer.send(frame(2, "STRING", "CMD_0001", 0,
                  body2(stringContent("START_UP"), 1, {{"Sender", 3, "Slicer 5.6"}})));
  std::vector<Frame> seen;
  ASSERT_TRUE(peer.until([](const Frame& f) { return f.device == "START_UP"; }, &seen))
      << "no result of START_UP";
  ASSERT_GE(seen.size(), 3u);
  EXPECT_EQ(seen[0].type, "STRING");
  EXPECT_EQ(seen[0].device, "ACK_0001");
  std::uint32_t last_id = 0;
  for (const auto& f : seen) {
    ASSERT_NO_FATAL_FAILURE(expectWellFramed(f));
    EXPECT_GT(f.message_id, last_id) << "message ids increase";
    last_id = f.message_id;
    ASSERT_NE(f.metaValue("RobotId"), nullptr) << f.device;
    EXPECT_EQ(*f.metaValue("RobotId"), server.robotId());
    ASSERT_NE(f.metaValue("Workphase"), nullptr) << f.device;
  }
  EXPECT_EQ(seen[0].stringText(), "START_UP");
  EXPECT_EQ(seen.back().statusCode(), 1);
  EXPECT_EQ(*seen.back().metaValue("Workphase"), "START_UP");

  // 2. COMMAND CALIBRATION (the workphase as protocol 3's command), answered by RTS_COMMAND with
  // its id and Slicer's Status attribute.
  peer.send(
      frame(2, "COMMAND", "COMMAND", 0,
            body2(commandContent(3, "CALIBRATION", "<Command Name=\"CALIBRATION\" />"), 2, {})));
  seen.clear();
  auto calibration = peer.until([](const Frame& f) { return f.type == "RTS_COMMAND"; }, &seen);
  ASSERT_TRUE(calibration.has_value());
  ASSERT_NO_FATAL_FAILURE(expectWellFramed(*calibration));
  EXPECT_EQ(calibration->device, "COMMAND");
  EXPECT_EQ(calibration->commandId(), 3u);
  EXPECT_EQ(calibration->commandName(), "CALIBRATION");
  EXPECT_EQ(attribute(calibration->commandText(), "Status"), "SUCCESS")
      << calibration->commandText();
  EXPECT_EQ(calibration->commandText().rfind("<Command ", 0), 0u) << calibration->commandText();
  const Frame* current = findFrame(seen, "STATUS", "CURRENT_STATUS");
  ASSERT_NE(current, nullptr);
  EXPECT_EQ(current->statusString(), "CALIBRATION");

  // 3. TRANSFORM CLB_0004 with a version-2 header and metadata: the echo, the result, the
  // registration Slicer shows, each with Units.
  float pose[3][4];
  calibrationPose(pose);
  peer.send(
      frame(2, "TRANSFORM", "CLB_0004", 0, body2(transformContent(pose), 3, {{"Units", 3, "mm"}})));
  seen.clear();
  ASSERT_TRUE(peer.until([](const Frame& f) { return f.device == "ImageToRobot"; }, &seen));
  const Frame* echo = findFrame(seen, "TRANSFORM", "ACK_0004");
  ASSERT_NE(echo, nullptr);
  ASSERT_NO_FATAL_FAILURE(expectWellFramed(*echo));
  EXPECT_EQ(echo->content, transformContent(pose)) << "the echo carries the float32s received";
  ASSERT_NE(echo->metaValue("Units"), nullptr);
  EXPECT_EQ(*echo->metaValue("Units"), "mm");
  const Frame* result = findFrame(seen, "STATUS", "CALIBRATION");
  ASSERT_NE(result, nullptr);
  EXPECT_EQ(result->statusCode(), 1) << result->statusString();

  // 4. One of ignav's own commands by its name in the command table: a target (RAS).
  const float c = pose[0][0], s = pose[1][0];
  // The robot-frame point (-10, 15, -190) in Slicer's RAS: p_ras = M^-1 (p - t).
  const double x = -10 - 12.5, y = 15 + 20.0, z = -190 + 40.0;
  const std::string points = std::to_string(c * x + s * y) + " " + std::to_string(-s * x + c * y) +
                             " " + std::to_string(z);
  peer.send(frame(2, "COMMAND", "COMMAND", 0,
                  body2(commandContent(5, "add_target",
                                       "<Command Name=\"add_target\" Points=\"" + points + "\" />"),
                        4, {})));
  auto added = peer.until([](const Frame& f) { return f.type == "RTS_COMMAND"; });
  ASSERT_TRUE(added.has_value());
  ASSERT_NO_FATAL_FAILURE(expectWellFramed(*added));
  EXPECT_EQ(added->commandId(), 5u);
  EXPECT_EQ(attribute(added->commandText(), "Status"), "SUCCESS") << added->commandText();
  EXPECT_EQ(attribute(added->commandText(), "TargetId"), "1") << added->commandText();
  auto viewer = server.client("viewer");
  const auto one_target = [](const json& st) {
    return st.contains("targets") && st["targets"].size() == 1u;
  };
  viewer->waitFor(one_target, 10s);

  // 5. Refused by name, nothing changed: an approver's command, an unknown one, bad XML, a bad
  // argument; each with its id.
  const struct {
    std::uint32_t id;
    const char* name;
    std::string xml;
    const char* code;
    const char* says;
  } refused[] = {
      {6, "home", "<Command Name=\"home\" />", "not_permitted", "approver"},
      {7, "no_such", "<Command />", "unknown_command", "no_such"},
      {8, "add_target", "<Command Name=\"add_target\" Points=\"1 2", "bad_command", "line 1"},
      {9, "add_target", "<Command Points=\"1 2 nan\" />", "bad_command", "Points"},
      {10, "add_target", "<Command Colour=\"red\" />", "bad_command", "Colour"},
      {11, "add_target", "<!DOCTYPE x [<!ENTITY a \"b\">]><Command />", "bad_command",
       "document type"},
  };
  for (const auto& r : refused) {
    peer.send(frame(2, "COMMAND", "COMMAND", 0, body2(commandContent(r.id, r.name, r.xml), 9, {})));
    auto answer = peer.until([](const Frame& f) { return f.type == "RTS_COMMAND"; });
    ASSERT_TRUE(answer.has_value()) << r.name;
    EXPECT_EQ(answer->commandId(), r.id);
    EXPECT_EQ(attribute(answer->commandText(), "Status"), "FAIL") << answer->commandText();
    EXPECT_EQ(attribute(answer->commandText(), "Code"), r.code) << answer->commandText();
    EXPECT_NE(attribute(answer->commandText(), "Message").find(r.says), std::string::npos)
        << answer->commandText();
  }
  EXPECT_TRUE(one_target(viewer->state()));

  // 6. Keep-alive: GET_STATUS in version 2 is answered by STATUS in version 2.
  peer.send(frame(2, "GET_STATUS", "CURRENT_STATUS", 0, body2("", 12, {})));
  auto status = peer.until([](const Frame& f) { return f.type == "STATUS"; });
  ASSERT_TRUE(status.has_value());
  ASSERT_NO_FATAL_FAILURE(expectWellFramed(*status));

  // 7. A late joiner is told the state at once: the workphase, the registration, the tip.
  Peer late(server.igtlPort());
  std::vector<Frame> told;
  ASSERT_TRUE(late.until([](const Frame& f) { return f.device == "NeedleTipToImage"; }, &told, 5s));
  ASSERT_EQ(told.size(), 3u);
  EXPECT_EQ(told[0].device, "CURRENT_STATUS");
  EXPECT_EQ(told[1].device, "ImageToRobot");
  for (const auto& f : told) {
    EXPECT_EQ(f.version, 1) << "not yet spoken: version 1";
    EXPECT_TRUE(f.crc_ok);
  }
}

TEST(Igtl3E2E, AStreamThatIsNotOpenIGTLinkLearnsWhyBeforeItIsLetGo) {
  ServerProcess server(178);
  Peer stranger(server.igtlPort());
  ASSERT_TRUE(stranger.next().has_value());  // the greeting
  // Header version 9: nothing after it can be framed.
  stranger.send(frame(9, "STRING", "CMD_0001", 0, stringContent("EMERGENCY")));
  auto why = stranger.until([](const Frame& f) { return f.device == "BAD_MESSAGE"; });
  ASSERT_TRUE(why.has_value()) << "the client was cut off without a word";
  EXPECT_TRUE(why->crc_ok);
  EXPECT_EQ(why->statusCode(), 12);
  EXPECT_NE(why->statusString().find("header version 9"), std::string::npos) << why->statusString();
  EXPECT_NE(why->statusString().find("CMD_0001"), std::string::npos) << why->statusString();
  EXPECT_FALSE(stranger.next(5s).has_value());
  EXPECT_TRUE(stranger.closed()) << "let go after the answer";
  // Inconsistent version-2 framing costs one message, not the connection; nothing changed.
  Peer client(server.igtlPort());
  ASSERT_TRUE(client.next().has_value());
  client.send(frame(2, "STRING", "CMD_0002", 0,
                    be(12, 2) + be(2, 2) + be(0, 4) + be(1, 4) + stringContent("EMERGENCY") +
                        be(5, 2)));  // five metadata entries in a two-byte metadata header
  auto bad = client.until([](const Frame& f) { return f.device == "BAD_MESSAGE"; });
  ASSERT_TRUE(bad.has_value());
  EXPECT_NE(bad->statusString().find("metadata header size 2"), std::string::npos)
      << bad->statusString();
  auto viewer = server.client("viewer");
  EXPECT_EQ(e2e::stateText(viewer->state(), "workflow", "phase"), "imaging");
  client.send(frame(2, "STRING", "CMD_0003", 0, body2(stringContent("START_UP"), 1, {})));
  auto ack = client.until([](const Frame& f) { return f.device == "ACK_0003"; });
  ASSERT_TRUE(ack.has_value());
  EXPECT_EQ(ack->version, 2);
}

TEST(Igtl3E2E, ThePlanningCtReachesAProtocol3ClientAsTheSeriesWithItsGeometry) {
  ServerProcess server(179);
  auto op = server.client("operator");
  Peer peer(server.igtlPort());
  ASSERT_TRUE(peer.next().has_value());  // the greeting
  const std::string ask = frame(2, "GET_IMAGE", "PlanningCT", 0, body2("", 1, {}));
  peer.send(ask);
  auto none = peer.until([](const Frame& f) { return f.device == "PlanningCT"; });
  ASSERT_TRUE(none.has_value());
  EXPECT_EQ(none->type, "STATUS");
  EXPECT_EQ(none->statusCode(), 13);
  EXPECT_EQ(none->statusErrorName(), "no_volume");

  e2e::registeredPhantom(*op);
  peer.send(ask);
  auto image = peer.until([](const Frame& f) { return f.type == "IMAGE"; }, nullptr, 60s);
  ASSERT_TRUE(image.has_value());
  ASSERT_NO_FATAL_FAILURE(expectWellFramed(*image));
  EXPECT_EQ(image->device, "PlanningCT");
  ASSERT_NE(image->metaValue("ValueUnits"), nullptr);
  EXPECT_EQ(*image->metaValue("ValueUnits"), "HU");

  // The series the server wrote for its phantom, read here.
  auto series = volume::readDicomSeries({(server.sessionDir() / "phantom_ct").string()});
  ASSERT_TRUE(series.ok()) << series.error().message;
  const volume::Volume& ct = series->volume;
  ASSERT_EQ(ct.value_scale, 1.0);  // stored as HU: sent as int16 as they are
  ASSERT_EQ(ct.value_offset, 0.0);
  const std::string& c = image->content;
  ASSERT_GE(c.size(), 72u);
  EXPECT_EQ(fromBe(c, 0, 2), 1u);  // image header version
  EXPECT_EQ(fromBe(c, 2, 1), 1u);  // one component
  EXPECT_EQ(fromBe(c, 3, 1), 4u);  // int16
  EXPECT_EQ(fromBe(c, 4, 1), 2u);  // little-endian
  EXPECT_EQ(fromBe(c, 5, 1), 1u);  // RAS
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(fromBe(c, 6 + 2 * a, 2), static_cast<std::uint64_t>(ct.geometry.dims[a]));
    EXPECT_EQ(fromBe(c, 60 + 2 * a, 2), 0u);
    EXPECT_EQ(fromBe(c, 66 + 2 * a, 2), static_cast<std::uint64_t>(ct.geometry.dims[a]));
  }
  // The axes and the centre, in RAS (x and y of LPS negated).
  const Eigen::Matrix4d ijk_lps = ct.geometry.ijkToLps();
  const Eigen::Vector3d ras(-1, -1, 1);
  for (int axis = 0; axis < 3; ++axis) {
    for (int r = 0; r < 3; ++r) {
      EXPECT_NEAR(floatAt(c, 12 + 12 * axis + 4 * r), ras[r] * ijk_lps(r, axis), 1e-5)
          << "axis " << axis << " row " << r;
    }
  }
  const Eigen::Vector4d middle((ct.geometry.dims[0] - 1) / 2.0, (ct.geometry.dims[1] - 1) / 2.0,
                               (ct.geometry.dims[2] - 1) / 2.0, 1.0);
  const Eigen::Vector3d centre_lps = (ijk_lps * middle).head<3>();
  for (int r = 0; r < 3; ++r)
    EXPECT_NEAR(floatAt(c, 48 + 4 * r), ras[r] * centre_lps[r], 1e-3);
  // Every voxel, as the series has it.
  ASSERT_EQ(c.size() - 72, ct.voxels.size() * 2);
  EXPECT_EQ(std::memcmp(c.data() + 72, ct.voxels.data(), ct.voxels.size() * 2), 0);
}

// A volume's IMAGE content as the peer writes it: int16 when its values are stored as they are,
// else float32 physical values; its axes and centre in RAS.
std::string imageOf(const volume::Volume& v) {
  const Eigen::Matrix4d ijk_lps = v.geometry.ijkToLps();
  const Eigen::Vector3d ras(-1, -1, 1);
  double axes[3][3], centre[3];
  const Eigen::Vector4d middle((v.geometry.dims[0] - 1) / 2.0, (v.geometry.dims[1] - 1) / 2.0,
                               (v.geometry.dims[2] - 1) / 2.0, 1.0);
  const Eigen::Vector4d c = ijk_lps * middle;
  for (int r = 0; r < 3; ++r) {
    for (int a = 0; a < 3; ++a)
      axes[a][r] = ras[r] * ijk_lps(r, a);
    centre[r] = ras[r] * c[r];
  }
  const bool as_stored = v.value_scale == 1.0 && v.value_offset == 0.0;
  std::string voxels;
  if (as_stored) {
    voxels.assign(reinterpret_cast<const char*>(v.voxels.data()), 2 * v.voxels.size());
  } else {
    for (const std::int16_t stored : v.voxels) {
      const auto f = static_cast<float>(stored * v.value_scale + v.value_offset);
      voxels.append(reinterpret_cast<const char*>(&f), 4);
    }
  }
  return imageContent(as_stored ? 4 : 10, 1, v.geometry.dims.data(), axes, centre, voxels);
}

// What a scanner bridge does: the confirmation CT sent as an IMAGE. The server keeps it in the
// session folder as it came, measures it as load_confirmation measures a file (the same rows as
// the DICOM series it was made from, measured over DDS), tells the sender when it is taken and
// when it is measured, and sends it back on GET_IMAGE; images it cannot take are refused by name,
// the session unchanged. DDS domain 189.
TEST(Igtl3E2E, AConfirmationCtSentAsAnImageIsKeptMeasuredAndSentBack) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("ignav_igtl3_scan_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  ServerProcess server(189, {"--controller-speed", "40000"});
  auto op = server.client("operator");
  e2e::insertAll(*op, {{8, 12, -175}, {-6, 10, -182}});
  const auto [status, text] =
      e2e::runPlan("confirmation-phantom " + server.sessionDir().string() +
                       " --robot " IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml --out " +
                       (dir / "scan").string() + " --noise-hu 8 --seed 3",
                   true);
  ASSERT_EQ(status, 0) << text;
  auto series = volume::readDicomSeries({(dir / "scan").string()});
  ASSERT_TRUE(series.ok()) << series.error().message;
  const volume::Volume& scan = series->volume;

  Peer peer(server.igtlPort());
  ASSERT_TRUE(peer.next().has_value());  // the greeting
  const auto answerTo = [&](const std::string& device) {
    return peer.until([&](const Frame& f) { return f.type == "STATUS" && f.device == device; },
                      nullptr, 60s);
  };
  // Refused by name, nothing kept or measured: a name that is no scan, two components, axes that
  // are not perpendicular.
  const int tiny[3] = {2, 2, 2};
  const double axes[3][3] = {{-1, 0, 0}, {0, -1, 0}, {0, 0, 1}};
  const double skewed[3][3] = {{-1, 0, 0}, {0.5, -1, 0}, {0, 0, 1}};
  const double centre[3] = {0, 0, -180};
  peer.send(frame(2, "IMAGE", "Banana", 0,
                  body2(imageContent(4, 1, tiny, axes, centre, std::string(16, '\1')), 1, {})));
  auto refused = answerTo("Banana");
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->statusCode(), 4);
  EXPECT_EQ(refused->statusErrorName(), "unknown_image");
  EXPECT_NE(refused->statusString().find("ConfirmationCT"), std::string::npos);
  peer.send(frame(2, "IMAGE", "ConfirmationCT", 0,
                  body2(imageContent(4, 2, tiny, axes, centre, std::string(32, '\1')), 2, {})));
  refused = answerTo("ConfirmationCT");
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->statusErrorName(), "bad_image") << refused->statusString();
  peer.send(frame(2, "IMAGE", "ConfirmationCT", 0,
                  body2(imageContent(4, 1, tiny, skewed, centre, std::string(16, '\1')), 3, {})));
  refused = answerTo("ConfirmationCT");
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->statusErrorName(), "bad_geometry") << refused->statusString();
  // An intermittent CT with no insertion paused: kept, then refused by the core, in its words.
  peer.send(frame(2, "IMAGE", "IntermittentCT", 0,
                  body2(imageContent(4, 1, tiny, axes, centre, std::string(16, '\1')), 4, {})));
  refused = answerTo("IntermittentCT");
  ASSERT_TRUE(refused.has_value());
  ASSERT_NO_FATAL_FAILURE(expectWellFramed(*refused));
  EXPECT_NE(refused->statusCode(), 1) << refused->statusString();
  EXPECT_FALSE(refused->statusString().empty());
  EXPECT_EQ(op->state()["verification"]["status"], "none");

  // The scan, as a scanner bridge sends it: taken, then measured.
  peer.send(
      frame(2, "IMAGE", "ConfirmationCT", 0, body2(imageOf(scan), 5, {{"Modality", 3, "CT"}})));
  auto taken = answerTo("ConfirmationCT");
  ASSERT_TRUE(taken.has_value());
  ASSERT_NO_FATAL_FAILURE(expectWellFramed(*taken));
  EXPECT_EQ(taken->statusCode(), 1) << taken->statusString();
  EXPECT_EQ(taken->statusErrorName(), "measuring");
  auto outcome = answerTo("ConfirmationCT");
  ASSERT_TRUE(outcome.has_value());
  ASSERT_NO_FATAL_FAILURE(expectWellFramed(*outcome));
  EXPECT_EQ(outcome->statusCode(), 1) << outcome->statusString();
  EXPECT_EQ(outcome->statusErrorName(), "measured") << outcome->statusString();

  // Kept in the session folder, every voxel and the geometry as sent (float32 on the wire).
  op->waitFor([](const json& s) { return s["verification"]["status"] == "measured"; }, 10s);
  const json by_image = op->state()["verification"];
  const std::string kept = by_image["source"];
  EXPECT_EQ(std::filesystem::path(kept).parent_path(), server.sessionDir() / "received");
  auto file = volume::readNrrd(kept);
  ASSERT_TRUE(file.ok()) << file.error().message;
  ASSERT_EQ(file->geometry.dims, scan.geometry.dims);
  EXPECT_LT((file->geometry.ijkToLps() - scan.geometry.ijkToLps()).cwiseAbs().maxCoeff(), 1e-3);
  for (std::size_t v = 0; v < scan.voxels.size(); ++v) {
    ASSERT_EQ(file->voxels[v] * file->value_scale + file->value_offset,
              scan.voxels[v] * scan.value_scale + scan.value_offset)
        << v;
  }

  // Sent back as it was measured.
  peer.send(frame(2, "GET_IMAGE", "ConfirmationCT", 0, body2("", 6, {})));
  auto back = peer.until([](const Frame& f) { return f.type == "IMAGE"; }, nullptr, 60s);
  ASSERT_TRUE(back.has_value());
  ASSERT_NO_FATAL_FAILURE(expectWellFramed(*back));
  EXPECT_EQ(back->device, "ConfirmationCT");
  const std::string sent = imageOf(scan);
  ASSERT_EQ(back->content.size(), sent.size());
  EXPECT_EQ(back->content.compare(72, std::string::npos, sent, 72, std::string::npos), 0);
  for (std::size_t at = 12; at < 60; at += 4)
    EXPECT_NEAR(floatAt(back->content, at), floatAt(sent, at), 1e-3) << at;

  // The same scan as its DICOM series, over DDS: the same rows.
  const auto r = op->send("load_confirmation", {(dir / "scan").string(), {}, {}});
  ASSERT_TRUE(r.accepted) << r.message;
  op->waitFor(
      [&](const json& s) {
        return s["workflow"]["revision"].get<std::uint64_t>() > r.revision &&
               s["verification"]["status"] != "measuring";
      },
      60s);
  const json by_dds = op->state()["verification"];
  ASSERT_EQ(by_dds["status"], "measured") << by_dds.dump();
  ASSERT_EQ(by_dds["targets"].size(), 2u);
  ASSERT_EQ(by_image["targets"].size(), 2u);
  for (std::size_t t = 0; t < 2; ++t) {
    EXPECT_EQ(by_image["targets"][t]["target_id"], by_dds["targets"][t]["target_id"]);
    EXPECT_NEAR(by_image["targets"][t]["error_mm"].get<double>(),
                by_dds["targets"][t]["error_mm"].get<double>(), 0.02)
        << by_image["targets"][t].dump() << " " << by_dds["targets"][t].dump();
  }
  std::filesystem::remove_all(dir);
}

// POLYDATA's content as the description lays it out: ten counts and sizes; the points; the
// vertices, lines, polygons and strips as (n, indices...) arrays; per attribute its type, its
// components and its count; the names, each NUL-terminated, padded to an even length; the values.
struct PeerPolyData {
  std::vector<float> points;
  std::vector<std::uint32_t> cells[4];  // vertices, lines, polygons, strips
  struct Attribute {
    int type = 0, components = 0;
    std::string name;
    std::vector<float> values;
  };
  std::vector<Attribute> attributes;
};

PeerPolyData readPolyData(const std::string& c) {
  PeerPolyData p;
  const std::uint64_t points = fromBe(c, 0, 4);
  std::size_t at = 40;
  for (std::uint64_t i = 0; i < 3 * points; ++i, at += 4)
    p.points.push_back(floatAt(c, at));
  for (int k = 0; k < 4; ++k) {
    for (std::uint64_t i = 0; i < fromBe(c, 8 + 8 * k, 4) / 4; ++i, at += 4)
      p.cells[k].push_back(static_cast<std::uint32_t>(fromBe(c, at, 4)));
  }
  std::vector<std::uint64_t> counts;
  for (std::uint64_t i = 0; i < fromBe(c, 36, 4); ++i, at += 6) {
    PeerPolyData::Attribute a;
    a.type = static_cast<int>(fromBe(c, at, 1));
    a.components = static_cast<int>(fromBe(c, at + 1, 1));
    counts.push_back(fromBe(c, at + 2, 4));
    p.attributes.push_back(a);
  }
  std::size_t names = 0;
  for (auto& a : p.attributes) {
    a.name = std::string(c.c_str() + at);
    at += a.name.size() + 1;
    names += a.name.size() + 1;
  }
  at += names % 2;
  for (std::size_t i = 0; i < p.attributes.size(); ++i) {
    auto& a = p.attributes[i];
    for (std::uint64_t v = 0; v < counts[i] * static_cast<std::uint64_t>(a.components);
         ++v, at += 4)
      a.values.push_back(floatAt(c, at));
  }
  EXPECT_EQ(at, c.size()) << "the parts add up to the content";
  return p;
}

Eigen::Vector3d pointOf(const std::vector<float>& xyz, std::size_t i) {
  return {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
}

// A closed mesh's signed volume (divergence theorem): positive when it is wound outwards.
double signedVolume(const std::vector<float>& xyz, const std::vector<std::uint32_t>& triangles,
                    std::size_t step, std::size_t first) {
  double six_v = 0.0;
  for (std::size_t t = first; t + 2 < triangles.size(); t += step) {
    six_v += pointOf(xyz, triangles[t])
                 .dot(pointOf(xyz, triangles[t + 1]).cross(pointOf(xyz, triangles[t + 2])));
  }
  return six_v / 6.0;
}

// The 3D view's surfaces and the planned paths as POLYDATA: every surface the scene has over DDS,
// turned into RAS point for point and still wound outwards (the same enclosed volume, positive);
// each planned path a polyline ending at its target, its points naming the target. Asked before
// there is anything: refused by name. DDS domain 190.
TEST(Igtl3E2E, SurfacesAndPathsReachAProtocol3ClientAsPolyData) {
  ServerProcess server(190);
  auto op = server.client("operator");
  Peer peer(server.igtlPort());
  ASSERT_TRUE(peer.next().has_value());  // the greeting
  std::uint32_t id = 0;
  const auto ask = [&](const std::string& device) {
    peer.send(frame(2, "GET_POLYDATA", device, 0, body2("", ++id, {})));
  };
  const auto answerTo = [&](const std::string& device) {
    return peer.until([&](const Frame& f) { return f.device == device; }, nullptr, 60s);
  };
  ask("PlannedPaths");
  auto refused = answerTo("PlannedPaths");
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->type, "STATUS");
  EXPECT_EQ(refused->statusErrorName(), "not_registered");
  ask("FeasibleVolume");
  refused = answerTo("FeasibleVolume");
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->statusErrorName(), "unknown_surface") << refused->statusString();

  e2e::registeredPhantom(*op);
  ASSERT_TRUE(op->send("load_structures", {"phantom:", {}, {}}).accepted);
  op->waitFor([](const json& s) { return e2e::stateText(s, "structures", "status") == "loaded"; },
              60s);
  const std::vector<Eigen::Vector3d> targets_lps = {e2e::lpsOf(op->state(), {8, 12, -175}),
                                                    e2e::lpsOf(op->state(), {-6, 10, -182})};
  std::vector<std::uint32_t> target_ids;
  for (const auto& lps : targets_lps) {
    const auto added = op->send("add_target", {"", {lps}, {}});
    ASSERT_TRUE(added.accepted) << added.message;
    target_ids.push_back(added.target_id);
  }
  const auto scene = op->scene("surfaces", 0, 0, 60s);
  ASSERT_TRUE(scene.ok) << scene.message;
  ASSERT_GE(scene.surfaces.size(), 2u);  // the structures and the feasible volume

  ask("");  // everything
  std::vector<Frame> polys;
  ASSERT_TRUE(peer.until(
      [&](const Frame& f) {
        if (f.type == "POLYDATA") polys.push_back(f);
        return polys.size() == scene.surfaces.size() + 1;
      },
      nullptr, 60s))
      << polys.size() << " POLYDATA of " << scene.surfaces.size() + 1;
  const Eigen::Vector3d ras(-1, -1, 1);
  for (const auto& f : polys) {
    ASSERT_NO_FATAL_FAILURE(expectWellFramed(f));
    ASSERT_NE(f.metaValue("Units"), nullptr) << f.device;
    EXPECT_EQ(*f.metaValue("Units"), "mm");
    const PeerPolyData p = readPolyData(f.content);
    if (f.device == "PlannedPaths") {
      ASSERT_EQ(p.attributes.size(), 1u);
      EXPECT_EQ(p.attributes[0].name, "TargetId");
      EXPECT_EQ(p.attributes[0].type, 0);  // per point
      std::size_t at = 0, path = 0;
      for (; at < p.cells[1].size(); at += p.cells[1][at] + 1, ++path) {
        ASSERT_LT(path, targets_lps.size());
        const std::uint32_t n = p.cells[1][at];
        ASSERT_GE(n, 2u);
        const std::uint32_t last = p.cells[1][at + n];
        const Eigen::Vector3d end = pointOf(p.points, last);
        EXPECT_LT((end - ras.cwiseProduct(targets_lps[path])).norm(), 0.05)
            << "path " << path << " ends at " << end.transpose();
        for (std::uint32_t i = 1; i <= n; ++i)
          EXPECT_EQ(p.attributes[0].values[p.cells[1][at + i]], target_ids[path]);
      }
      EXPECT_EQ(path, targets_lps.size());
      continue;
    }
    ASSERT_NE(f.metaValue("Name"), nullptr) << f.device;
    const protocol::SceneSurface* same = nullptr;
    for (const auto& surface : scene.surfaces)
      if (surface.name == *f.metaValue("Name")) same = &surface;
    ASSERT_NE(same, nullptr) << *f.metaValue("Name");
    EXPECT_EQ(f.device,
              same->kind == "feasible" ? std::string("FeasibleVolume") : same->name.substr(0, 20));
    ASSERT_EQ(p.points.size(), same->points_lps.size()) << f.device;
    for (std::size_t i = 0; i < p.points.size(); ++i)
      ASSERT_EQ(p.points[i], (i % 3 == 2 ? 1.0f : -1.0f) * same->points_lps[i]) << f.device;
    ASSERT_EQ(p.cells[2].size(), same->triangles.size() / 3 * 4) << f.device;
    const double lps_mm3 = signedVolume(same->points_lps, same->triangles, 3, 0);
    const double ras_mm3 = signedVolume(p.points, p.cells[2], 4, 1);
    EXPECT_GT(lps_mm3, 0.0) << f.device;
    EXPECT_NEAR(ras_mm3, lps_mm3, 1e-6 * lps_mm3) << f.device << ": wound outwards in RAS";
  }

  ask("Banana");
  refused = answerTo("Banana");
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->statusErrorName(), "unknown_surface");
  EXPECT_NE(refused->statusString().find("FeasibleVolume"), std::string::npos)
      << refused->statusString();
}

// The translation of a TDATA frame's first element (name at 0, type at 20, 12 floats from 22).
Eigen::Vector3d tdataTip(const Frame& f) {
  return {floatAt(f.content, 22 + 36), floatAt(f.content, 22 + 40), floatAt(f.content, 22 + 44)};
}

TEST(Igtl3E2E, TheTipStreamsAsTdataWhileTheRobotMovesStampedWhenItWasRead) {
  ServerProcess server(186, {"--igtl-tip-rate", "50", "--controller-speed", "20000"});
  auto op = server.client("operator");
  const std::uint32_t target = e2e::lockedPlanTo(*op, {-10, 15, -190});
  Peer peer(server.igtlPort());
  ASSERT_TRUE(peer.next().has_value());  // the greeting
  // STT_TDATA in version 2: resolution 0 ms (as fast as the server streams), no coordinate name.
  peer.send(frame(2, "STT_TDATA", "NeedleTip", 0, body2(be(0, 4) + std::string(32, '\0'), 1, {})));
  const double before_s = nowS();
  ASSERT_TRUE(e2e::approveShown(*op).accepted);
  std::vector<Frame> seen;
  // Until the tip has come to rest: the arrival's STATUS follows the last moving frame.
  ASSERT_TRUE(
      peer.until([](const Frame& f) { return f.type == "STATUS" && f.device == "MOVE_TO_TARGET"; },
                 &seen, 60s));
  // The at-rest frame comes from the listener's next tick.
  (void)peer.until([](const Frame& f) { return f.type == "TDATA"; }, &seen, 2s);
  std::vector<const Frame*> tdata;
  for (const auto& f : seen)
    if (f.type == "TDATA") tdata.push_back(&f);
  ASSERT_GE(tdata.size(), 3u) << "the tip streamed while it moved";
  double last_s = before_s - 1.0;
  for (const Frame* f : tdata) {
    ASSERT_NO_FATAL_FAILURE(expectWellFramed(*f));
    EXPECT_EQ(f->device, "NeedleTip");
    ASSERT_EQ(f->content.size(), 70u);
    EXPECT_EQ(nameField(f->content, 0, 20), "NeedleTip");
    EXPECT_EQ(fromBe(f->content, 20, 1), 2u);  // a 6D instrument
    const double stamped = static_cast<double>(f->timestamp >> 32) +
                           static_cast<double>(f->timestamp & 0xffffffffULL) / 4294967296.0;
    EXPECT_GE(stamped, last_s) << "stamps never go back";
    EXPECT_GE(stamped, before_s - 0.5);
    last_s = stamped;
  }
  // It comes to rest on the target: the target's LPS position in RAS.
  const json state = op->state();
  const Eigen::Vector3d target_lps = e2e::vec(e2e::targetState(state, target)["lps"]);
  const Eigen::Vector3d target_ras(-target_lps.x(), -target_lps.y(), target_lps.z());
  EXPECT_LT((tdataTip(*tdata.back()) - target_ras).norm(), 0.05)
      << tdataTip(*tdata.back()).transpose() << " vs " << target_ras.transpose();
  // STP_TDATA: no more.
  peer.send(frame(2, "STP_TDATA", "NeedleTip", 0, body2("", 2, {})));
}

}  // namespace
}  // namespace ignav::igtl3_test
