// What an OpenIGTLink client can send: a byte stream (well-formed BRP messages with fuzzed
// fields in header version 1 or 2 with fuzzed metadata, COMMANDs with fuzzed XML, version-2
// frames whose extended header, metadata header and metadata sizes lie but whose CRC is right,
// POLYDATA whose counts and sizes lie, headers announcing enormous bodies, corrupted messages, raw
// garbage) split at fuzzed points, through the Decoder and the BRP bridge, with the bridge's inputs
// through the real reducer as the server runs them, from a registered planning session. Checked on
// every message: the decoder holds no more than a body limit and a chunk; every STRING(CMD_<id>) is
// receipted first with ACK_<id>; everything the bridge answers can be encoded; nothing moves except
// by an approval of the pending plan (DESIGN.md safety invariants 1 and 5).
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "fuzz_session.hpp"
#include "ignav/igtl/brp.hpp"
#include "ignav/workflow/reducer.hpp"

namespace {

using namespace ignav;
using workflow::Input;
using workflow::InputKind;
using workflow::Session;

constexpr std::size_t kBodyLimit = 4096;

// Registered, planning; the bridge may approve (the riskiest setting).
const Session& planningSession() {
  static const Session s = fuzz::planningSession({igtl::kBridgeClientId});
  return s;
}

double fuzzedNumber(FuzzedDataProvider& in) {
  switch (in.ConsumeIntegralInRange<int>(0, 5)) {
    case 0:
      return std::numeric_limits<double>::quiet_NaN();
    case 1:
      return std::numeric_limits<double>::infinity();
    case 2:
      return in.ConsumeFloatingPointInRange<double>(-1.0, 1.0);  // rotation-like
    case 3:
      return in.ConsumeFloatingPointInRange<double>(-200.0, 200.0);
    default:
      return in.ConsumeFloatingPoint<double>();
  }
}

// One message on the wire: mostly well formed (our encoder, fuzzed fields), sometimes damaged.
std::string fuzzedMessage(FuzzedDataProvider& in) {
  static const char* kPhases[] = {"START_UP",       "PLANNING", "CALIBRATION", "TARGETING",
                                  "MOVE_TO_TARGET", "MANUAL",   "STOP",        "EMERGENCY"};
  static const char* kPrefixes[] = {"CMD_", "CLB_", "TGT_", "ACK_", ""};
  igtl::Message m;
  const int kind = in.ConsumeIntegralInRange<int>(0, 8);
  m.device_name = std::string(kPrefixes[in.ConsumeIntegralInRange<int>(0, 4)]) +
                  in.ConsumeRandomLengthString(8);
  if (m.device_name.size() > igtl::kMaxDeviceName) m.device_name.resize(igtl::kMaxDeviceName);
  switch (kind) {
    case 0:
      m.type = "STRING";
      m.text = in.ConsumeBool() ? kPhases[in.ConsumeIntegralInRange<int>(0, 7)]
                                : in.ConsumeRandomLengthString(64);
      break;
    case 1:
    case 2:
      m.type = "TRANSFORM";
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c)
          m.matrix(r, c) = in.ConsumeBool() ? m.matrix(r, c) : fuzzedNumber(in);
      break;
    case 3:
      m.type = "POINT";
      for (std::size_t i = in.ConsumeIntegralInRange<std::size_t>(0, 4); i > 0; --i) {
        m.points.push_back({in.ConsumeRandomLengthString(8), "TARGET",
                            Eigen::Vector3d(fuzzedNumber(in), fuzzedNumber(in), fuzzedNumber(in))});
      }
      break;
    case 4:
      m.type = "GET_STATUS";
      break;
    case 5:
    case 6: {
      static const char* kNames[] = {
          "START_UP",    "MOVE_TO_TARGET", "EMERGENCY",        "add_target", "home", "approve",
          "load_volume", "remove_target",  "set_registration", "query",      ""};
      static const char* kAttributes[] = {"Name", "Points", "Ids", "Path", "Matrix", "X"};
      m = igtl::commandMessage("COMMAND", in.ConsumeIntegral<std::uint32_t>(),
                               kNames[in.ConsumeIntegralInRange<int>(0, 10)], "");
      if (in.ConsumeBool()) {
        std::string xml = "<Command";
        for (std::size_t i = in.ConsumeIntegralInRange<std::size_t>(0, 3); i > 0; --i) {
          xml += std::string(" ") + kAttributes[in.ConsumeIntegralInRange<int>(0, 5)] + "=\"" +
                 in.ConsumeRandomLengthString(40) + "\"";
        }
        m.command.text = xml + (in.ConsumeBool() ? " />" : in.ConsumeRandomLengthString(16));
      } else {
        m.command.text = in.ConsumeRandomLengthString(120);
      }
      break;
    }
    case 7: {
      if (in.ConsumeBool()) {
        Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 4; ++c)
            pose(r, c) = in.ConsumeBool() ? pose(r, c) : fuzzedNumber(in);
        m = igtl::trackingMessage(in.ConsumeRandomLengthString(24), pose);
        break;
      }
      // A small IMAGE (a scanner bridge's confirmation CT, in miniature), fuzzed geometry.
      igtl::Image image;
      image.size = {in.ConsumeIntegralInRange<int>(0, 6), in.ConsumeIntegralInRange<int>(0, 6),
                    in.ConsumeIntegralInRange<int>(0, 4)};
      image.scalar_type = in.ConsumeBool() ? igtl::ScalarType::kInt16 : igtl::ScalarType::kFloat32;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c)
          image.ijk_to_mm(r, c) = in.ConsumeBool() ? image.ijk_to_mm(r, c) : fuzzedNumber(in);
      auto voxels = std::make_shared<std::string>(in.ConsumeRandomLengthString(600));
      image.data = std::shared_ptr<const char>(voxels, voxels->data());
      image.data_bytes = voxels->size();
      m = igtl::imageMessage("ConfirmationCT", std::move(image));
      break;
    }
    default:
      m.type = "GET_TRANS";
      break;
  }
  if (in.ConsumeBool()) {
    m.header_version = 2;
    m.message_id = in.ConsumeIntegral<std::uint32_t>();
    for (std::size_t i = in.ConsumeIntegralInRange<std::size_t>(0, 3); i > 0; --i) {
      m.metadata.push_back({in.ConsumeRandomLengthString(12), in.ConsumeIntegral<std::uint16_t>(),
                            in.ConsumeRandomLengthString(24)});
    }
  }
  auto bytes = igtl::encode(m);
  std::string wire = bytes ? *bytes : in.ConsumeRandomLengthString(100);
  if (!wire.empty() && in.ConsumeIntegralInRange<int>(0, 7) == 0) {
    wire[in.ConsumeIntegralInRange<std::size_t>(0, wire.size() - 1)] ^=
        static_cast<char>(1 + in.ConsumeIntegralInRange<int>(0, 254));
  }
  return wire;
}

// A version-2 frame whose body's sizes are fuzzed (its CRC right, so that the sizes are what is
// judged), or a bare header announcing a body of any size, up to 2^64 - 1.
std::string fuzzedFraming(FuzzedDataProvider& in) {
  igtl::Header h;
  h.version = in.ConsumeBool() ? 2 : in.ConsumeIntegral<std::uint16_t>();
  static const char* kTypes[] = {"STRING", "COMMAND", "POLYDATA"};
  h.type = kTypes[in.ConsumeIntegralInRange<int>(0, 2)];
  h.device_name = "CMD_1";
  if (in.ConsumeIntegralInRange<int>(0, 5) == 0) {
    h.body_size = in.ConsumeBool() ? ~0ULL : in.ConsumeIntegral<std::uint64_t>();
    return igtl::writeHeader(h);
  }
  const auto be = [](std::uint64_t v, int n) {
    std::string out;
    for (int i = n - 1; i >= 0; --i)
      out += static_cast<char>((v >> (8 * i)) & 0xff);
    return out;
  };
  std::string body = be(in.ConsumeBool() ? 12 : in.ConsumeIntegral<std::uint16_t>(), 2);
  const std::size_t count = in.ConsumeIntegralInRange<std::size_t>(0, 4);
  body += be(in.ConsumeBool() ? 2 + 8 * count : in.ConsumeIntegral<std::uint16_t>(), 2);
  body += be(in.ConsumeIntegralInRange<std::uint32_t>(0, in.ConsumeBool() ? 64 : 0xffffffffu), 4);
  body += be(in.ConsumeIntegral<std::uint32_t>(), 4);
  if (h.type == "POLYDATA") {  // ten counts and sizes that may lie, then what they describe
    for (int i = 0; i < 10; ++i) {
      body += be(in.ConsumeBool() ? 4 * in.ConsumeIntegralInRange<std::uint32_t>(0, 8)
                                  : in.ConsumeIntegral<std::uint32_t>(),
                 4);
    }
    body += in.ConsumeRandomLengthString(240);
  } else {
    body += in.ConsumeRandomLengthString(60);  // content
  }
  body += be(count, 2);
  for (std::size_t i = 0; i < count; ++i) {
    body += be(in.ConsumeIntegralInRange<std::uint16_t>(0, 16), 2) + be(3, 2) +
            be(in.ConsumeIntegralInRange<std::uint32_t>(0, in.ConsumeBool() ? 16 : 0xffffffffu), 4);
  }
  body += in.ConsumeRandomLengthString(64);  // keys and values
  h.body_size = body.size();
  h.crc = igtl::crc64(body);
  return igtl::writeHeader(h) + body;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  Session session = planningSession();
  igtl::BrpBridge bridge({true}, 1);
  igtl::Decoder decoder(kBodyLimit, kBodyLimit * 4);
  std::vector<igtl::BrpOutgoing> sent;
  std::vector<Input> queue;

  // The server's part: inputs through the reducer, replies back to the bridge.
  const auto take = [&](igtl::BrpOutput out) {
    for (auto& m : out.messages)
      sent.push_back(std::move(m));
    for (auto& i : out.inputs)
      queue.push_back(std::move(i));
  };
  const auto run = [&] {
    while (!queue.empty()) {
      Input i = std::move(queue.front());
      queue.erase(queue.begin());
      i.time_s = 1000.0;
      if (workflow::needsControllerReading(i.kind)) {
        actuation::ControllerStatus idle;
        idle.state = actuation::ControllerState::kIdle;
        idle.position = session.position;
        i.controller = idle;
      }
      const auto pending_before = session.pending;
      const auto step = workflow::reduce(session, i);
      for (const auto& c : step.effects.controller) {
        if (c.action() != workflow::ControllerAction::kMove) continue;
        // Only an approval of exactly the pending plan releases a move.
        if (i.kind != InputKind::kApprove || !pending_before ||
            pending_before->plan_id != i.plan_id || pending_before->digest != i.digest) {
          std::abort();
        }
      }
      session = step.session;
      for (const auto& r : step.effects.replies)
        take(bridge.onReply(r, session));
      take(bridge.onState(session));
    }
  };

  for (int n = 0; n < 24 && in.remaining_bytes() > 0; ++n) {
    std::string wire;
    switch (in.ConsumeIntegralInRange<int>(0, 3)) {
      case 0:
      case 1:
        wire = fuzzedMessage(in);
        break;
      case 2:
        wire = fuzzedFraming(in);
        break;
      default:
        wire = in.ConsumeRandomLengthString(80);
        break;
    }
    // Split anywhere.
    for (std::size_t at = 0; at < wire.size();) {
      const std::size_t chunk =
          std::min(wire.size() - at, in.ConsumeIntegralInRange<std::size_t>(1, 200));
      decoder.feed(wire.data() + at, chunk);
      at += chunk;
      while (auto next = decoder.next()) {
        if (!next->ok()) {
          if (next->error().reason == "header_version") return 0;  // the connection would end
          continue;
        }
        const igtl::Message& m = next->value();
        sent.clear();
        auto out = bridge.onMessage(1, m, session, session.position);
        const auto scans = out.scans;
        take(std::move(out));
        // A scan taken: its geometry valid (the bridge checked it), kept or not, then measured.
        for (const auto& scan : scans) {
          if (!scan.geometry.validate("scan").ok() || !scan.voxels) std::abort();
          take(bridge.onScanSaved(scan, in.ConsumeBool() ? "/nonexistent/scan.nrrd" : "",
                                  in.ConsumeBool() ? "" : "disk full"));
        }
        const bool command =
            m.type == "STRING" && m.device_name.rfind("CMD_", 0) == 0 && m.device_name.size() > 4;
        if (command && (sent.empty() || sent.front().message.device_name !=
                                            ("ACK_" + m.device_name.substr(4)).substr(0, 20))) {
          std::abort();  // the receipt comes first, always
        }
        run();
        for (auto out : sent) {
          // Everything we answer can be sent, in either header version, with its metadata.
          if (!igtl::encode(out.message)) std::abort();
          bridge.annotate(out.message, session);
          out.message.header_version = 2;
          if (!igtl::encode(out.message)) std::abort();
        }
        if (m.header_version == 2) {
          // What was read is written back and read again as it was (the codec is its own inverse).
          auto again = igtl::encode(m);
          if (!again) continue;  // fields only a reader accepts (an over-long command text)
          igtl::Decoder echo(kBodyLimit + 1024);
          echo.feed(again->data(), again->size());
          auto back = echo.next();
          if (!back || !back->ok() || back->value().metadata != m.metadata ||
              back->value().message_id != m.message_id ||
              back->value().command.text != m.command.text ||
              back->value().command.name != m.command.name) {
            std::abort();
          }
        }
      }
      if (decoder.buffered() > 4 * kBodyLimit + igtl::kHeaderBytes + 200) std::abort();
    }
  }
  return 0;
}
