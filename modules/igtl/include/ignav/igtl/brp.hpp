// The ProstateBRP workphase protocol (3D Slicer's robot protocol over OpenIGTLink) translated to
// and from the workflow core. The bridge has no logic of its own: each BRP command becomes
// workflow inputs, and what the core answers becomes BRP replies. It holds only what the
// translation needs (which BRP command is waiting for which reply, the last workphase reported).
// Pure: no sockets, no clock; the server feeds it messages, replies and states
// (docs/OPENIGTLINK.md).
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "ignav/igtl/command_xml.hpp"
#include "ignav/igtl/message.hpp"
#include "ignav/volume/image_io.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::igtl {

enum class Workphase {
  kStartUp,
  kPlanning,
  kCalibration,
  kTargeting,
  kMoveToTarget,
  kManual,
  kStop,
  kEmergency
};
const char* toString(Workphase phase);  // "START_UP", "MOVE_TO_TARGET", ...
std::optional<Workphase> parseWorkphase(const std::string& text);

// Slicer works in RAS, ignav (as DICOM) in LPS: p_ras = kRasFromLps * p_lps (its own inverse).
Eigen::Matrix4d rasFromLps();

// The client id (and role) of every input the bridge sends. DDS clients may not use it.
inline constexpr const char* kBridgeClientId = "openigtlink";

// The revisions of the BRP protocol a site meets (server.yaml openigtlink.protocol; the message
// sequences of each, scenario by scenario: docs/OPENIGTLINK.md).
enum class Revision {
  // "slicer": what the current 3D Slicer module reads: the workphase in CURRENT_STATUS's status
  // string, told on connect and on every change; REACHABLE_TARGET; ImageToRobot and
  // NeedleTipToImage streamed.
  kSlicer,
  // "brp2013": the June 2013 revision exactly as its reference robots (the ProstateBRP
  // communication test's robot, the WPI robot) write it, for clients that read strictly in order:
  // nothing unasked; every command ACK_<id>, then CURRENT_STATUS (code 1, the requested
  // workphase in the error-name field), then its result; PLANNING and CALIBRATION have none (the
  // calibration's follows the CLB_ transform); TARGET; CURRENT_POSITION only.
  kBrp2013,
};
const char* toString(Revision revision);  // "slicer" | "brp2013"
std::optional<Revision> parseRevision(const std::string& text);

struct BrpOptions {
  // OpenIGTLink has no authentication: MOVE_TO_TARGET approves the motion only when a site
  // enables this (and lists kBridgeClientId as an approver); otherwise a DDS approver must.
  bool allow_motion_approval = false;
  Revision revision = Revision::kSlicer;
};

struct BrpOutgoing {
  std::uint64_t client = 0;  // 0: every connected client
  Message message;
};

// An IMAGE a client sent to be measured (a scanner bridge's scan): "ConfirmationCT" becomes
// load_confirmation, "IntermittentCT" scan_needle. The server keeps it in the session folder first
// (off the event thread, its voxels exactly as they came), then tells onScanSaved.
struct ReceivedScan {
  std::uint64_t client = 0;
  std::string device;
  volume::Geometry geometry;  // LPS
  volume::VoxelType type = volume::VoxelType::kInt16;
  std::shared_ptr<const char> voxels;  // as received (host byte order), shared with the message
  std::size_t bytes = 0;
};
// The IMAGE names a client may send, and what each becomes.
inline constexpr const char* kConfirmationScan = "ConfirmationCT";
inline constexpr const char* kIntermittentScan = "IntermittentCT";

// GET_POLYDATA of a surface the server makes off the event thread (structures, the feasible
// volume, isodoses): "" or "Scene" for all of them.
struct SurfaceRequest {
  std::uint64_t client = 0;
  std::string device;
};

struct BrpOutput {
  std::vector<BrpOutgoing> messages;
  std::vector<workflow::Input> inputs;  // for the core, in order; the server stamps time, reading
  std::vector<ReceivedScan> scans;      // to be saved, then onScanSaved
  std::vector<SurfaceRequest> surfaces;
};

class BrpBridge {
 public:
  // `first_request_id` must not repeat across server restarts (the core answers a repeated
  // request id from its journal without executing it): the server passes microseconds of wall time.
  BrpBridge(BrpOptions options, std::uint64_t first_request_id);

  // A client connected: it is told the workphase and, if registered, ImageToRobot and the tip.
  BrpOutput onConnected(std::uint64_t client, const workflow::Session& s) const;
  void onDisconnected(std::uint64_t client);
  // A message from a client. `live` is the motors' present position (for GET_TRANSFORM).
  BrpOutput onMessage(std::uint64_t client, const Message& m, const workflow::Session& s,
                      const actuation::Steps& live);
  // A received scan was saved at `path` (a path the server reads), or could not be (`error`): it
  // is measured as load_confirmation / scan_needle of that file would measure it, and the client
  // told (STATUS named after the scan) when the core takes it and, for a confirmation CT, when the
  // measurement ends.
  BrpOutput onScanSaved(const ReceivedScan& scan, const std::string& path,
                        const std::string& error);
  // The core's reply to one of our inputs (client id kBridgeClientId), with the session after it.
  BrpOutput onReply(const workflow::Reply& reply, const workflow::Session& s);
  // After every step: workphase changes, motion results, a new registration.
  BrpOutput onState(const workflow::Session& s);
  // While the robot moves: CURRENT_POSITION and NeedleTipToImage at the motors' live position.
  BrpOutput onPosition(const workflow::Session& s, const actuation::Steps& live) const;

  // The workphase a client would be told now.
  Workphase workphase(const workflow::Session& s) const;
  // What a protocol-3 client is told with every message, as metadata (version 1 has no room for
  // it): RobotId, Workphase, and Units "mm" on what carries coordinates. TargetId is set where a
  // message is about one target.
  void annotate(Message& m, const workflow::Session& s) const;
  bool waiting() const { return !pending_.empty(); }

 private:
  // kCommand: a workphase (STRING CMD_ or COMMAND); kOwnCommand: one of ignav's commands by its
  // name in the command table (COMMAND only).
  // kScan: a received scan's load_confirmation or scan_needle.
  enum class Purpose { kCommand, kCalibration, kTarget, kTargetRemoval, kOwnCommand, kScan };
  struct Pending {
    std::uint64_t client = 0;
    Purpose purpose = Purpose::kCommand;
    Workphase phase = Workphase::kStartUp;  // kCommand
    std::deque<workflow::InputKind> remaining;
    std::string why;  // kTargetRemoval: the core's reason the target cannot be reached
    // A COMMAND's id and name: answered with RTS_COMMAND (a STRING CMD_ with STATUS).
    std::optional<std::pair<std::uint32_t, std::string>> command;
    std::string scan, scan_path;  // kScan: the IMAGE's name, where it was kept
  };
  // A received confirmation CT being measured: its client is told the outcome.
  struct Measuring {
    std::uint64_t client = 0;
    std::string path;
  };
  void reportMeasurements(const workflow::Session& s, BrpOutput& out);
  static Pending pending(std::uint64_t client, Purpose purpose, Workphase phase,
                         std::string why = {});

  workflow::Input input(workflow::InputKind kind);
  // The inputs a workphase asks for, dispatched (STRING CMD_ and COMMAND alike).
  void startWorkphase(Pending p, const workflow::Session& s, BrpOutput& out);
  BrpOutput onCommand(std::uint64_t client, const Message& m, const workflow::Session& s);
  // The next input of a command (an approval is filled in from the session's pending request).
  void dispatch(Pending p, const workflow::Session& s, BrpOutput& out);
  Message currentStatus(const workflow::Session& s) const;
  bool brp2013() const { return options_.revision == Revision::kBrp2013; }
  // A refusal in the user's words: a command the phase does not allow says what the robot is
  // doing and what to send instead, not the core's input names.
  Message refusal(const char* device, const workflow::Reply& reply, Workphase asked,
                  const workflow::Session& s) const;
  void reportCurrentStatus(std::uint64_t client, const workflow::Session& s, BrpOutput& out);

  BrpOptions options_;
  std::uint64_t next_request_id_;
  std::map<std::uint64_t, Pending> pending_;  // by request id
  std::optional<Workphase> last_accepted_;    // none yet (or a replay: then from the phase)
  std::optional<std::pair<Workphase, std::uint16_t>> last_reported_;
  workflow::Phase last_phase_ = workflow::Phase::kStartup;
  bool halt_asked_ = false;  // a STOP / EMERGENCY of a client's interrupted the move
  std::optional<Eigen::Matrix4d> last_registration_;
  std::map<std::uint64_t, Measuring> measuring_;  // by the load_confirmation's job
};

// The needle tip's pose in the image (RAS): translation = the tip at `steps`, rotation = the
// robot frame's axes. Nothing without a registration.
std::optional<Eigen::Matrix4d> tipToImageRas(const workflow::Session& s,
                                             const actuation::Steps& steps);
// The core's rejection as a BRP STATUS code. slicer: panic in an emergency, manual mode, hardware
// failure, configuration error for bad values, not ready for the rest. brp2013 (as its reference
// robots): configuration error for bad values, not ready for everything else.
StatusCode statusCodeFor(const std::string& error_code, workflow::Phase phase,
                         Revision revision = Revision::kSlicer);
// GET_IMAGE's answer: "PlanningCT" or "ConfirmationCT" (the measured one; HU, float32 when the
// stored values are rescaled) or "Dose" (the latest computed, Gy, float32), in RAS with their
// geometry; a STATUS when there is none. The voxels are shared with the session, not copied.
Message imageFor(const std::string& name, const workflow::Session& s);

// GET_POLYDATA(PlannedPaths)'s answer: each planned target's needle path (needlePathLps of its
// commanded joints: the cannula, then the stylet's arc) as a polyline in RAS, in target order, a
// point scalar "TargetId" naming whose path each point is on (libOpenIGTLink misreads cell data);
// empty when no target is planned; a STATUS when not registered.
Message plannedPaths(const workflow::Session& s);
// A closed surface as POLYDATA (points LPS -> RAS, a half turn about S that keeps the triangles
// wound outwards), named `device`, its whole name, kind and colour as metadata.
Message surfaceMessage(std::string device, const std::string& name, const std::string& kind,
                       const std::array<double, 3>& colour_rgb,
                       const std::vector<float>& points_lps,
                       const std::vector<std::uint32_t>& triangles);
// The POLYDATA device name of a scene surface: "FeasibleVolume", "Isodose100" (its percentage),
// or the structure's name (cut to OpenIGTLink's 20 characters).
std::string surfaceDeviceName(const std::string& name, const std::string& kind);

// RTS_COMMAND answering COMMAND `id` named `name`: <Command Name=".." Status="SUCCESS|FAIL"
// Code="ok|<reply code>" Message=".." /> (Slicer's OpenIGTLinkRemote reads Status and Message).
Message commandReply(std::uint32_t id, const std::string& name, bool success,
                     const std::string& code, const std::string& message,
                     const XmlAttributes& more = {});

// The error-name field for a reply code of the core (docs/PROTOCOL.md): the code itself, or a
// short form of it where it is longer than the field's 19 characters (docs/OPENIGTLINK.md lists
// them).
std::string errorNameFor(const std::string& error_code);

}  // namespace ignav::igtl
