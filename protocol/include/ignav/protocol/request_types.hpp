// The requests and replies (protocol/idl/ignav.idl says what each field means): each value, its
// one list of fields (JSON name, member, C member(s)) and its topic. Part of types.hpp.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "ignav/protocol/fields.hpp"
#include "ignav/protocol/topics.hpp"
#include "ignav/protocol/values.hpp"

namespace ignav::protocol {

// One command. `kind` is its number in docs/PROTOCOL.md's table of commands
// (commands/command_table.hpp, protocol/commands.hpp); it travels on the command topic of its least
// role.
struct Command {
  std::string client_id;
  std::uint64_t request_id = 0;
  std::int32_t kind = 0;
  std::string path;
  std::vector<Point3> points;
  std::vector<std::uint32_t> ids;
  RowMajor4 matrix{};  // set_registration, load_confirmation (zeros: none): p_robot = M * p_lps
};
template <>
struct Fields<Command> {
  using T = Command;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(client_id), IGNAV_FIELD(request_id), IGNAV_FIELD(kind), IGNAV_FIELD(path),
      IGNAV_FIELD(points), IGNAV_FIELD(ids), IGNAV_FIELD(matrix));
};

// The most points or ids the server copies out of a Command: one more than any command may carry
// (planning.max_targets is at most 100), so that the workflow can name the oversize without the
// server holding an oversized sequence.
constexpr std::size_t kMaxCommandItemsRead = 101;

// The one reply to a command, an approval or an emergency stop.
struct Reply {
  std::string client_id;
  std::uint64_t request_id = 0;
  bool accepted = false;
  std::string error_code;           // "" when accepted (docs/PROTOCOL.md's table of codes)
  std::string message;              // for a person: names the field, value and limit
  std::uint32_t target_id = 0;      // add_target: the new id
  std::uint64_t revision = 0;       // the workflow revision after the command
  double server_time_unix_s = 0.0;  // when the server took the command (ping's answer)
  std::uint64_t job = 0;  // the background job the command started (JobOutcome.job); 0: none
};
template <>
struct Fields<Reply> {
  using T = Reply;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(client_id), IGNAV_FIELD(request_id), IGNAV_FIELD(accepted),
                      IGNAV_FIELD(error_code), IGNAV_FIELD(message), IGNAV_FIELD(target_id),
                      IGNAV_FIELD(revision), IGNAV_FIELD(server_time_unix_s), IGNAV_FIELD(job));
};
IGNAV_TOPIC_OF(Reply, topic::kReply, Qos::kRequest);

// What became of a background job the server ran (load_volume's CT load, auto_fiducials' marker
// detection, load_confirmation's measurement): wait for the one whose job is the command's
// Reply.job.
struct JobOutcome {
  std::uint64_t job = 0;
  std::string kind;    // "CT load", "marker detection", "confirmation CT measurement"
  std::string input;   // the outcome input: "fiducials_detected", ...
  std::string status;  // done | failed | stale (no longer awaited: changed nothing)
  std::string message;
  std::uint64_t revision = 0;
};
template <>
struct Fields<JobOutcome> {
  using T = JobOutcome;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(job), IGNAV_FIELD(kind), IGNAV_FIELD(input), IGNAV_FIELD(status),
                      IGNAV_FIELD(message), IGNAV_FIELD(revision));
};
IGNAV_TOPIC_OF(JobOutcome, topic::kJobOutcome, Qos::kStateOfMany);

struct Approval {
  std::string client_id;
  std::uint64_t request_id = 0;
  std::uint64_t plan_id = 0;
  std::string digest;  // ApprovalState.digest, exactly
};
template <>
struct Fields<Approval> {
  using T = Approval;
  static constexpr auto list = std::make_tuple(IGNAV_FIELD(client_id), IGNAV_FIELD(request_id),
                                               IGNAV_FIELD(plan_id), IGNAV_FIELD(digest));
};
IGNAV_TOPIC_OF(Approval, topic::kApproval, Qos::kRequest);

struct EmergencyStop {
  std::string client_id;
  std::uint64_t request_id = 0;
};
template <>
struct Fields<EmergencyStop> {
  using T = EmergencyStop;
  static constexpr auto list = std::make_tuple(IGNAV_FIELD(client_id), IGNAV_FIELD(request_id));
};
IGNAV_TOPIC_OF(EmergencyStop, topic::kEmergencyStop, Qos::kRequest);

struct SliceRequest {
  std::string client_id;
  std::uint64_t request_id = 0;
  std::string view;  // axial | coronal | sagittal
  Point3 centre_lps;
  std::uint32_t size_px = 0;  // 0: fit the volume
  double pixel_mm = 0.0;      // 0: the finest spacing
  double window = 0.0;        // <= 0: the CT preset
  double level = 0.0;
  bool overlays = false;     // fiducials, targets and the feasible region
  bool region_only = false;  // with overlays: the feasible region and the structures only
};
template <>
struct Fields<SliceRequest> {
  using T = SliceRequest;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(client_id), IGNAV_FIELD(request_id), IGNAV_FIELD(view), IGNAV_FIELD(centre_lps),
      IGNAV_FIELD(size_px), IGNAV_FIELD(pixel_mm), IGNAV_FIELD(window), IGNAV_FIELD(level),
      IGNAV_FIELD(overlays), IGNAV_FIELD(region_only));
};
IGNAV_TOPIC_OF(SliceRequest, topic::kSliceRequest, Qos::kRequest);

struct SliceReply {
  std::string client_id;
  std::uint64_t request_id = 0;
  bool ok = false;
  std::string message;
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  RowMajor4 pixel_to_lps{};  // LPS = M * (u, v, 0, 1), u right, v down
  std::vector<std::uint8_t> png;
};
template <>
struct Fields<SliceReply> {
  using T = SliceReply;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(client_id), IGNAV_FIELD(request_id), IGNAV_FIELD(ok), IGNAV_FIELD(message),
      IGNAV_FIELD(width), IGNAV_FIELD(height), IGNAV_FIELD(pixel_to_lps), IGNAV_FIELD(png));
};
IGNAV_TOPIC_OF(SliceReply, topic::kSliceReply, Qos::kRequest);

// The scene of a 3D view (issue 43): the CT by slabs, the surfaces in one reply.
struct SceneRequest {
  std::string client_id;
  std::uint64_t request_id = 0;
  std::string part;                       // volume | surfaces
  std::uint32_t max_voxels_per_axis = 0;  // volume: 0 = 256
  std::uint32_t first_slice = 0;          // volume: the slab's first k
};
template <>
struct Fields<SceneRequest> {
  using T = SceneRequest;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(client_id), IGNAV_FIELD(request_id), IGNAV_FIELD(part),
                      IGNAV_FIELD(max_voxels_per_axis), IGNAV_FIELD(first_slice));
};
IGNAV_TOPIC_OF(SceneRequest, topic::kSceneRequest, Qos::kRequest);

struct SceneSurface {
  std::string name;
  std::string kind;  // structure | feasible | isodose
  std::array<double, 3> colour_rgb{};
  std::vector<float> points_lps;         // x, y, z per vertex (mm)
  std::vector<std::uint32_t> triangles;  // three vertex indices per triangle, wound outwards
};
template <>
struct Fields<SceneSurface> {
  using T = SceneSurface;
  static constexpr auto list =
      std::make_tuple(IGNAV_FIELD(name), IGNAV_FIELD(kind), IGNAV_FIELD(colour_rgb),
                      IGNAV_FIELD(points_lps), IGNAV_FIELD(triangles));
};

struct SceneReply {
  std::string client_id;
  std::uint64_t request_id = 0;
  bool ok = false;
  std::string message;
  std::string part;
  std::string volume_id;  // slabs of different ids do not belong together
  std::array<std::uint32_t, 3> dims{};
  RowMajor4 ijk_to_lps{};
  double value_scale = 1.0;
  double value_offset = 0.0;
  std::uint32_t first_slice = 0;
  std::uint32_t slice_count = 0;
  std::vector<std::int16_t> voxels;  // the slab, i fastest
  std::vector<SceneSurface> surfaces;
};
template <>
struct Fields<SceneReply> {
  using T = SceneReply;
  static constexpr auto list = std::make_tuple(
      IGNAV_FIELD(client_id), IGNAV_FIELD(request_id), IGNAV_FIELD(ok), IGNAV_FIELD(message),
      IGNAV_FIELD(part), IGNAV_FIELD(volume_id), IGNAV_FIELD(dims), IGNAV_FIELD(ijk_to_lps),
      IGNAV_FIELD(value_scale), IGNAV_FIELD(value_offset), IGNAV_FIELD(first_slice),
      IGNAV_FIELD(slice_count), IGNAV_FIELD(voxels), IGNAV_FIELD(surfaces));
};
IGNAV_TOPIC_OF(SceneReply, topic::kSceneReply, Qos::kRequest);

}  // namespace ignav::protocol
