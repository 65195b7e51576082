// What a browser and the gateway say to each other over the WebSocket (docs/WEB.md), translated
// to and from the DDS client's terms. Pure: no sockets, no DDS, so every bad input is testable.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "ignav/protocol/client.hpp"
#include "ignav/protocol/commands.hpp"

namespace ignav::web {

// Bounds on what one browser message may carry (the server has its own, lower, limits: this only
// keeps a gateway from parsing and queueing without end).
constexpr std::size_t kMaxMessageBytes = 1 << 20;
constexpr std::size_t kMaxPoints = 128;
constexpr std::size_t kMaxIds = 128;

struct CommandRequest {
  std::string kind;  // a command name, "add_target", ...
  protocol::CommandArgs args;
};
struct ApproveRequest {
  std::uint64_t plan_id = 0;
  std::string digest;
};
struct EmergencyStopRequest {};
struct SliceRequest {
  protocol::SliceArgs args;
};
struct SceneRequest {  // a part of the 3D view's scene (issue 43)
  std::string part;    // volume | surfaces
  std::uint32_t first_slice = 0;
  std::uint32_t max_voxels_per_axis = 0;
};

struct BrowserRequest {
  std::uint64_t seq = 0;
  std::variant<CommandRequest, ApproveRequest, EmergencyStopRequest, SliceRequest, SceneRequest>
      body;
};

// A message the gateway refuses before it reaches the server; `seq` when it could be read.
struct BadRequest {
  std::optional<std::uint64_t> seq;
  std::string message;  // names the field and what is wrong with it
};

// Parses one WebSocket text frame from a browser.
std::variant<BrowserRequest, BadRequest> parseBrowserMessage(std::string_view text);

// Gateway -> browser.
// `permitted`: the commands (and "approve") this gateway's identity may publish at all;
// `robot_id`: the one robot it serves.
nlohmann::json helloMessage(const std::string& client_id, const std::string& robot_id,
                            const std::string& subject, bool security, const std::string& version,
                            const std::vector<std::string>& permitted);
nlohmann::json connectionMessage(bool server_matched);
// `changed`: topic names as protocol::Client::poll() returns them ("target" is sent as the whole
// "targets" map). Empty `changed`: the whole state.
nlohmann::json stateMessage(const nlohmann::json& state, const std::vector<std::string>& changed);
nlohmann::json replyMessage(std::uint64_t seq, const protocol::Reply& reply);
// What became of a background job (every browser hears it; the one whose reply named the job
// waits for it).
nlohmann::json jobOutcomeMessage(const protocol::JobOutcome& outcome);
nlohmann::json sliceMessage(std::uint64_t seq, const protocol::SliceResult& slice);
// The numbers travel as base64 of their little-endian bytes (int16 voxels, float32 points,
// uint32 triangle indices): a 256-cube CT is 32 MiB of voxels, not a JSON array.
nlohmann::json sceneMessage(std::uint64_t seq, const protocol::SceneReply& scene);
// code: bad_request | timeout | busy | no_server | failed
nlohmann::json errorMessage(std::optional<std::uint64_t> seq, const std::string& code,
                            const std::string& message);

// Standard base64 (RFC 4648, padded), for PNG bytes inside JSON.
std::string base64(const std::vector<std::uint8_t>& bytes);
std::string base64(const void* bytes, std::size_t size);

}  // namespace ignav::web
