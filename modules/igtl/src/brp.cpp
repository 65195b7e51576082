#include "ignav/igtl/brp.hpp"

#include <algorithm>
#include <initializer_list>
#include <sstream>

#include <fmt/format.h>

#include "ignav/workflow/reducer.hpp"

namespace ignav::igtl {
namespace {

using workflow::InputKind;
using workflow::Phase;

// A STRING's device is "CMD_<id>" (a TRANSFORM's "CLB_<id>" / "TGT_<id>"): the id, if it is one.
std::optional<std::string> idAfter(const std::string& device, const char* prefix) {
  const std::string p = prefix;
  if (device.size() <= p.size() || device.compare(0, p.size(), p) != 0) return std::nullopt;
  return device.substr(p.size());
}

std::string ackName(const std::string& id) {
  return ("ACK_" + id).substr(0, kMaxDeviceName);
}

Eigen::Matrix4d poseRas(const workflow::Session& s, const Eigen::Vector3d& robot_mm) {
  const auto& reg = *s.registration;
  const Eigen::Matrix4d f = rasFromLps();
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  // Robot axes in the image: rotation^T (image -> robot is scale * rotation), then LPS -> RAS.
  pose.topLeftCorner<3, 3>() = f.topLeftCorner<3, 3>() * reg.rotation.transpose();
  pose.topRightCorner<3, 1>() = f.topLeftCorner<3, 3>() * reg.toImage(robot_mm);
  return pose;
}

}  // namespace

std::optional<Eigen::Matrix4d> tipToImageRas(const workflow::Session& s,
                                             const actuation::Steps& steps) {
  if (!s.registration || !s.robot) return std::nullopt;
  const auto joints = s.robot->transmission.toJoints(steps);
  return poseRas(s, s.robot->kinematics.forward(joints).tip_mm);
}

BrpBridge::BrpBridge(BrpOptions options, std::uint64_t first_request_id)
    : options_(options), next_request_id_(first_request_id) {}

Workphase BrpBridge::workphase(const workflow::Session& s) const {
  switch (s.phase) {
    case Phase::kStartup:
      return Workphase::kStartUp;
    case Phase::kMoving:
      return Workphase::kMoveToTarget;
    case Phase::kStopped:
      return Workphase::kStop;
    case Phase::kEmergency:
      return Workphase::kEmergency;
    case Phase::kManual:
      return Workphase::kManual;
    default:
      break;
  }
  // Otherwise the workphase the navigation software last asked for, if the robot is still where
  // that left it; else (a DDS client moved the workflow on, or nothing was asked yet, as in a
  // replay) the one the phase implies.
  const auto fits = [&](std::initializer_list<Workphase> allowed) {
    return last_accepted_ &&
           std::find(allowed.begin(), allowed.end(), *last_accepted_) != allowed.end();
  };
  using W = Workphase;
  switch (s.phase) {
    case Phase::kImaging:
    case Phase::kRegistration:
      return fits({W::kStartUp, W::kPlanning, W::kCalibration}) ? *last_accepted_ : W::kStartUp;
    case Phase::kPlanning:
      return fits({W::kStartUp, W::kPlanning, W::kCalibration, W::kTargeting}) ? *last_accepted_
                                                                               : W::kPlanning;
    case Phase::kPlanLocked:
      return fits({W::kStartUp, W::kTargeting, W::kMoveToTarget}) ? *last_accepted_ : W::kTargeting;
    case Phase::kAtTarget:
    case Phase::kDone:
      return fits({W::kStartUp, W::kTargeting, W::kMoveToTarget}) ? *last_accepted_
                                                                  : W::kMoveToTarget;
    default:  // a fault keeps the workphase it interrupted
      return last_accepted_.value_or(W::kStartUp);
  }
}

Message BrpBridge::currentStatus(const workflow::Session& s) const {
  StatusCode code = StatusCode::kOk;
  std::string error;
  if (s.phase == Phase::kEmergency) {
    code = StatusCode::kPanic;
    error = "emergency";
  } else if (s.phase == Phase::kManual) {
    code = StatusCode::kManualMode;
    error = "manual";
  } else if (s.phase == Phase::kFault) {
    code = StatusCode::kHardwareFailure;
    error = "fault";
  }
  return statusMessage("CURRENT_STATUS", code, toString(workphase(s)), error);
}

// Every client hears of a new workphase; the client whose command left it unchanged is told
// it again (each command is answered with the workphase).
void BrpBridge::reportCurrentStatus(std::uint64_t client, const workflow::Session& s,
                                    BrpOutput& out) {
  Message status = currentStatus(s);
  const auto now = std::make_pair(workphase(s), status.status.code);
  const bool changed = !last_reported_ || *last_reported_ != now;
  last_reported_ = now;
  out.messages.push_back({changed ? 0 : client, std::move(status)});
}

Message BrpBridge::refusal(const char* device, const workflow::Reply& reply, Workphase asked,
                           const workflow::Session& s) const {
  std::string text = reply.message;
  if (reply.error_code == "wrong_phase") {
    // The core names its own inputs ("request_approval is not allowed in manual"): a Slicer user
    // needs the workphase asked for, what the robot is doing, and what to send.
    const char* now = "";
    switch (s.phase) {
      case Phase::kManual:
        now = "the robot is under manual control; send START_UP to take it back";
        break;
      case Phase::kEmergency:
        now = "the robot is in an emergency stop; an approver resets it (ignavctl)";
        break;
      case Phase::kFault:
        now = "the robot has a fault; an approver resets it once it is mended";
        break;
      case Phase::kStopped:
        now = "the robot is stopped; send START_UP or the workphase to go on with";
        break;
      case Phase::kMoving:
        now = "the robot is moving; wait for it, or send STOP";
        break;
      default:
        now = "the robot is not ready for it";
        break;
    }
    text = fmt::format("{} is not possible now: {}", toString(asked), now);
  }
  return statusMessage(device, statusCodeFor(reply.error_code, s.phase, options_.revision), text,
                       errorNameFor(reply.error_code));
}

workflow::Input BrpBridge::input(InputKind kind) {
  workflow::Input in;
  in.kind = kind;
  in.client_id = kBridgeClientId;
  in.role = kBridgeClientId;
  in.request_id = next_request_id_++;
  return in;
}

BrpOutput BrpBridge::onConnected(std::uint64_t client, const workflow::Session& s) const {
  BrpOutput out;
  if (brp2013()) return out;  // its robots say nothing until asked
  out.messages.push_back({client, currentStatus(s)});
  if (s.registration) {
    out.messages.push_back(
        {client, transformMessage("ImageToRobot", s.registration->imageToRobot() * rasFromLps())});
    // Where the tip is (the last verified position; the stream follows it while it moves).
    out.messages.push_back(
        {client, transformMessage("NeedleTipToImage", *tipToImageRas(s, s.position))});
  }
  return out;
}

void BrpBridge::onDisconnected(std::uint64_t client) {
  // Its commands still run to their end (the robot must not be left half-way through a
  // sequence); their answers go nowhere.
  for (auto& [id, p] : pending_) {
    if (p.client == client) p.client = ~std::uint64_t{0};
  }
  for (auto it = measuring_.begin(); it != measuring_.end();) {
    it = it->second.client == client ? measuring_.erase(it) : std::next(it);
  }
}

namespace {

// An IMAGE sent to be measured: a scan to keep (its geometry checked), or why not.
BrpOutput scanFrom(std::uint64_t client, const Message& m) {
  BrpOutput out;
  const auto refuse = [&](StatusCode code, const std::string& why, const char* error_name) {
    out.messages.push_back({client, statusMessage(m.device_name, code, why, error_name)});
    return out;
  };
  const std::string name = fmt::format("IMAGE '{}'", m.device_name);
  if (m.device_name != kConfirmationScan && m.device_name != kIntermittentScan) {
    return refuse(StatusCode::kNotFound,
                  fmt::format("{}: the images taken here are {} (measured as load_confirmation) "
                              "and {} (as scan_needle)",
                              name, kConfirmationScan, kIntermittentScan),
                  "unknown_image");
  }
  const Image& image = m.image;
  if (image.components != 1) {
    return refuse(StatusCode::kConfigurationError,
                  fmt::format("{}: {} components per voxel; a CT has one", name,
                              static_cast<int>(image.components)),
                  "bad_image");
  }
  ReceivedScan scan;
  switch (image.scalar_type) {
    case ScalarType::kInt8:
      scan.type = volume::VoxelType::kInt8;
      break;
    case ScalarType::kUint8:
      scan.type = volume::VoxelType::kUInt8;
      break;
    case ScalarType::kInt16:
      scan.type = volume::VoxelType::kInt16;
      break;
    case ScalarType::kUint16:
      scan.type = volume::VoxelType::kUInt16;
      break;
    case ScalarType::kInt32:
      scan.type = volume::VoxelType::kInt32;
      break;
    case ScalarType::kUint32:
      scan.type = volume::VoxelType::kUInt32;
      break;
    case ScalarType::kFloat32:
      scan.type = volume::VoxelType::kFloat;
      break;
    case ScalarType::kFloat64:
      scan.type = volume::VoxelType::kDouble;
      break;
  }
  // IJK -> LPS; its columns are the axes times the spacing.
  const Eigen::Matrix4d to_lps =
      image.ras ? Eigen::Matrix4d(rasFromLps() * image.ijk_to_mm) : image.ijk_to_mm;
  volume::Geometry& g = scan.geometry;
  g.dims = image.size;
  for (int a = 0; a < 3; ++a) {
    g.spacing_mm[a] = to_lps.col(a).head<3>().norm();
    g.direction.col(a) = to_lps.col(a).head<3>() / g.spacing_mm[a];
  }
  g.origin_lps_mm = to_lps.topRightCorner<3, 1>();
  if (auto valid = g.validate(name); !valid.ok()) {
    return refuse(StatusCode::kConfigurationError, valid.error().message, "bad_geometry");
  }
  scan.client = client;
  scan.device = m.device_name;
  scan.voxels = image.data;
  scan.bytes = image.data_bytes;
  out.scans.push_back(std::move(scan));
  return out;
}

}  // namespace

BrpOutput BrpBridge::onMessage(std::uint64_t client, const Message& m, const workflow::Session& s,
                               const actuation::Steps& live) {
  BrpOutput out;
  const auto send = [&](Message msg) { out.messages.push_back({client, std::move(msg)}); };
  if (m.type == "STRING") {
    const auto id = idAfter(m.device_name, "CMD_");
    if (!id) {
      send(statusMessage(m.device_name, StatusCode::kUnknownInstruction,
                         "a command is STRING(CMD_<id>, <workphase>)", "unknown_device"));
      return out;
    }
    // The receipt first, whatever becomes of the command.
    send(stringMessage(ackName(*id), m.text));
    const auto phase = parseWorkphase(m.text);
    if (brp2013() && phase) {
      // Then the workphase asked for, before anything is tried: the result says how it went.
      send(statusMessage("CURRENT_STATUS", StatusCode::kOk, "", toString(*phase)));
    }
    if (!phase) {
      if (!brp2013()) send(currentStatus(s));
      send(statusMessage(m.text.substr(0, kMaxDeviceName), StatusCode::kUnknownInstruction,
                         fmt::format("'{}' is not a workphase", m.text.substr(0, 64)),
                         "unknown_workphase"));
      return out;
    }
    Pending p;
    p.client = client;
    p.phase = *phase;
    startWorkphase(std::move(p), s, out);
    return out;
  }
  if (m.type == "COMMAND") return onCommand(client, m, s);
  if (m.type == "IMAGE") return scanFrom(client, m);
  if (m.type == "TRANSFORM") {
    const auto clb = idAfter(m.device_name, "CLB_");
    const auto tgt = idAfter(m.device_name, "TGT_");
    if (!clb && !tgt) {
      send(statusMessage(m.device_name, StatusCode::kUnknownInstruction,
                         "a transform is CLB_<id> (registration) or TGT_<id> (target)",
                         "unknown_device"));
      return out;
    }
    send(transformMessage(ackName(clb ? *clb : *tgt), m.matrix));  // the echo, as received
    if (clb) {
      auto in = input(InputKind::kSetRegistration);
      // Slicer's matrix maps RAS to the robot: p_robot = M p_ras = (M F) p_lps.
      in.matrix = m.matrix * rasFromLps();
      pending_[in.request_id] = pending(client, Purpose::kCalibration, Workphase::kCalibration);
      out.inputs.push_back(std::move(in));
    } else {
      auto in = input(InputKind::kAddTarget);
      in.points.push_back(rasFromLps().topLeftCorner<3, 3>() * m.matrix.topRightCorner<3, 1>());
      pending_[in.request_id] = pending(client, Purpose::kTarget, Workphase::kTargeting);
      out.inputs.push_back(std::move(in));
    }
    return out;
  }
  if (m.type == "POINT") {
    // Slicer's markups: each point a target, echoed as received.
    Message echo = m;
    echo.device_name = ackName(m.device_name);
    send(std::move(echo));
    if (m.points.size() > workflow::kMaxTargets) {
      send(statusMessage("TARGET", StatusCode::kConfigurationError,
                         fmt::format("{} points in one message; at most {}", m.points.size(),
                                     workflow::kMaxTargets),
                         "oversized"));
      return out;
    }
    for (const auto& point : m.points) {
      auto in = input(InputKind::kAddTarget);
      in.points.push_back(rasFromLps().topLeftCorner<3, 3>() * point.position_mm);
      pending_[in.request_id] = pending(client, Purpose::kTarget, Workphase::kTargeting);
      out.inputs.push_back(std::move(in));
    }
    return out;
  }
  if (m.type == "GET_STATUS") {
    // brp2013: the reference robots answer with a STATUS named after the workphase.
    send(brp2013() ? statusMessage(toString(workphase(s)), StatusCode::kOk) : currentStatus(s));
    return out;
  }
  if (m.type == "GET_TRANS") {  // GET_TRANSFORM (type names are 12 characters at most)
    if (m.device_name == "ImageToRobot") {
      if (s.registration) {
        send(transformMessage("ImageToRobot", s.registration->imageToRobot() * rasFromLps()));
      } else {
        send(statusMessage("ImageToRobot", StatusCode::kNotReady, "not registered yet",
                           "not_registered"));
      }
      return out;
    }
    if (m.device_name == "CURRENT_POSITION" || m.device_name == "NeedleTipToImage" ||
        m.device_name.empty()) {
      const std::string name = m.device_name.empty() ? "CURRENT_POSITION" : m.device_name;
      if (auto pose = tipToImageRas(s, live)) {
        send(transformMessage(name, *pose));
      } else {
        send(statusMessage(name, StatusCode::kNotReady,
                           "not registered yet: the tip has no image position", "not_registered"));
      }
      return out;
    }
    send(statusMessage(m.device_name, StatusCode::kNotFound,
                       "transforms here: CURRENT_POSITION, NeedleTipToImage, ImageToRobot",
                       "unknown_transform"));
    return out;
  }
  // The tip stream is the listener's to pace (server/igtl_listener.cpp): nothing to answer here.
  if (m.type == "STT_TDATA" || m.type == "STP_TDATA") return out;
  if (m.type == "GET_POLYDATA") {
    // The paths are the session's own (cheap); the surfaces are made on the slices thread.
    const bool all = m.device_name.empty() || m.device_name == "Scene";
    if (all || m.device_name == "PlannedPaths") send(plannedPaths(s));
    if (m.device_name != "PlannedPaths") out.surfaces.push_back({client, m.device_name});
    return out;
  }
  if (m.type == "GET_IMAGE") {
    send(imageFor(m.device_name.empty() ? std::string("PlanningCT") : m.device_name, s));
    return out;
  }
  // Stream controls and other queries: nothing of ours streams on request.
  send(statusMessage(m.device_name, StatusCode::kUnknownInstruction,
                     fmt::format("{} is not part of the BRP protocol here", m.type),
                     "unknown_message"));
  return out;
}

BrpBridge::Pending BrpBridge::pending(std::uint64_t client, Purpose purpose, Workphase phase,
                                      std::string why) {
  Pending p;
  p.client = client;
  p.purpose = purpose;
  p.phase = phase;
  p.why = std::move(why);
  return p;
}

BrpOutput BrpBridge::onScanSaved(const ReceivedScan& scan, const std::string& path,
                                 const std::string& error) {
  BrpOutput out;
  if (!error.empty()) {
    out.messages.push_back(
        {scan.client, statusMessage(scan.device, StatusCode::kResourceError,
                                    "the scan could not be kept: " + error, "not_saved")});
    return out;
  }
  auto in = input(scan.device == kConfirmationScan ? InputKind::kLoadConfirmation
                                                   : InputKind::kScanNeedle);
  in.path = path;
  Pending p;
  p.client = scan.client;
  p.purpose = Purpose::kScan;
  p.scan = scan.device;
  p.scan_path = path;
  pending_[in.request_id] = std::move(p);
  out.inputs.push_back(std::move(in));
  return out;
}

void BrpBridge::reportMeasurements(const workflow::Session& s, BrpOutput& out) {
  const workflow::Confirmation& c = s.confirmation;
  for (auto it = measuring_.begin(); it != measuring_.end();) {
    if (c.measuring == it->first) {
      ++it;
      continue;
    }
    const std::string& path = it->second.path;
    const bool measured = c.source == path && (c.status == "measured" || c.status == "unmatched");
    const bool about_it = c.source == path || c.message.find(path) != std::string::npos;
    out.messages.push_back(
        {it->second.client,
         statusMessage(kConfirmationScan,
                       measured ? StatusCode::kOk : StatusCode::kConfigurationError,
                       about_it ? c.message : path + ": a later scan was measured instead",
                       measured ? c.status : "not_measured")});
    it = measuring_.erase(it);
  }
}

void BrpBridge::startWorkphase(Pending p, const workflow::Session& s, BrpOutput& out) {
  // Unlock and lock are sent only where the phase then calls for them (dispatch decides).
  auto& r = p.remaining;
  switch (p.phase) {
    case Workphase::kStartUp:
      // START_UP takes the robot back from a stop or from manual control.
      if (s.phase == Phase::kStopped || s.phase == Phase::kManual) r.push_back(InputKind::kResume);
      r.push_back(InputKind::kCheckReady);
      break;
    case Workphase::kPlanning:
    case Workphase::kCalibration:
    case Workphase::kTargeting:
      if (s.phase == Phase::kStopped) r.push_back(InputKind::kResume);
      // Editing targets again: the plan is unlocked (what was reached stays reached).
      if (p.phase != Workphase::kCalibration) r.push_back(InputKind::kUnlockPlan);
      r.push_back(InputKind::kCheckReady);
      break;
    case Workphase::kMoveToTarget:
      if (s.phase == Phase::kStopped) r.push_back(InputKind::kResume);
      r.push_back(InputKind::kLockPlan);
      r.push_back(options_.allow_motion_approval ? InputKind::kApprove
                                                 : InputKind::kRequestApproval);
      break;
    case Workphase::kManual:
      r.push_back(InputKind::kManual);
      break;
    case Workphase::kStop:
      r.push_back(InputKind::kStop);
      break;
    case Workphase::kEmergency:
      r.push_back(InputKind::kEmergencyStop);
      break;
  }
  // A move this client halts is answered by the halt's own result, not as interrupted.
  if ((p.phase == Workphase::kStop || p.phase == Workphase::kEmergency) &&
      s.phase == Phase::kMoving) {
    halt_asked_ = true;
  }
  dispatch(std::move(p), s, out);
}

namespace {

// "x y z; x y z" (or commas): points of a COMMAND's Points attribute.
std::optional<std::vector<Eigen::Vector3d>> pointsIn(const std::string& text) {
  std::vector<Eigen::Vector3d> out;
  std::string cleaned = text;
  std::replace(cleaned.begin(), cleaned.end(), ',', ' ');
  std::size_t start = 0;
  while (start <= cleaned.size()) {
    const std::size_t end = std::min(cleaned.find(';', start), cleaned.size());
    std::istringstream in(cleaned.substr(start, end - start));
    Eigen::Vector3d p;
    std::string extra;
    if (!(in >> p.x() >> p.y() >> p.z()) || (in >> extra) || !p.allFinite()) return std::nullopt;
    out.push_back(p);
    start = end + 1;
  }
  return out;
}

template <class T>
std::optional<std::vector<T>> numbersIn(const std::string& text) {
  std::string cleaned = text;
  std::replace(cleaned.begin(), cleaned.end(), ',', ' ');
  std::istringstream in(cleaned);
  std::vector<T> out;
  T v;
  while (in >> v)
    out.push_back(v);
  if (!in.eof()) return std::nullopt;
  return out;
}

}  // namespace

BrpOutput BrpBridge::onCommand(std::uint64_t client, const Message& m, const workflow::Session& s) {
  BrpOutput out;
  const auto answer = [&](bool ok, const std::string& code, const std::string& text) {
    out.messages.push_back({client, commandReply(m.command.id, m.command.name, ok, code, text)});
  };
  auto xml = parseCommandXml(m.command.text);
  if (!xml) {
    answer(false, "bad_command", xml.error().message);
    return out;
  }
  const std::string* named = xml->attribute("Name");
  std::string name = m.command.name.empty() && named ? *named : m.command.name;
  if (named && *named != name) {
    answer(false, "bad_command",
           fmt::format("the XML's Name '{}' is not the command's name '{}'", *named, name));
    return out;
  }
  if (const auto phase = parseWorkphase(name)) {
    Pending p;
    p.client = client;
    p.phase = *phase;
    p.command = std::make_pair(m.command.id, name);
    startWorkphase(std::move(p), s, out);
    return out;
  }
  const commands::InputSpec* spec = commands::commandNamed(name);
  if (!spec) {
    answer(false, "unknown_command",
           fmt::format("'{}' is neither a BRP workphase nor one of ignav's commands "
                       "(docs/PROTOCOL.md lists them)",
                       name.substr(0, 64)));
    return out;
  }
  if (spec->role == commands::ClientRole::kApprover) {
    // OpenIGTLink has no authentication: what an approver may do is asked over DDS.
    answer(false, "not_permitted",
           fmt::format("{} is an approver's command: over OpenIGTLink (unauthenticated) only "
                       "viewers' and planners' commands are taken; an approver gives it over DDS",
                       spec->name));
    return out;
  }
  auto in = input(spec->kind);
  for (const auto& [key, value] : xml->attributes) {
    if (key == "Name") continue;
    if (key == "Path") {
      in.path = value;
    } else if (key == "Points") {  // RAS, as Slicer's
      const auto points = pointsIn(value);
      if (!points) {
        answer(false, "bad_command", "Points: 'x y z; x y z ...' in mm (RAS), finite numbers");
        return out;
      }
      for (const auto& p : *points)
        in.points.push_back(rasFromLps().topLeftCorner<3, 3>() * p);
    } else if (key == "Ids") {
      const auto ids = numbersIn<std::uint32_t>(value);
      if (!ids) {
        answer(false, "bad_command", "Ids: whole numbers separated by spaces");
        return out;
      }
      in.ids = *ids;
    } else if (key == "Matrix") {  // row-major, mapping RAS as Slicer's CLB_ transform does
      const auto numbers = numbersIn<double>(value);
      if (!numbers || numbers->size() != 16) {
        answer(false, "bad_command", "Matrix: 16 numbers, row by row");
        return out;
      }
      Eigen::Matrix4d matrix;
      for (int i = 0; i < 16; ++i)
        matrix(i / 4, i % 4) = (*numbers)[static_cast<std::size_t>(i)];
      if (!matrix.allFinite()) {
        answer(false, "bad_command", "Matrix: a number is not finite");
        return out;
      }
      in.matrix = matrix * rasFromLps();
    } else {
      answer(false, "bad_command",
             fmt::format("attribute '{}': a command's arguments are Path, Points, Ids, Matrix",
                         key.substr(0, 32)));
      return out;
    }
  }
  Pending p;
  p.client = client;
  p.purpose = Purpose::kOwnCommand;
  p.command = std::make_pair(m.command.id, name);
  pending_[in.request_id] = std::move(p);
  out.inputs.push_back(std::move(in));
  return out;
}

void BrpBridge::dispatch(Pending p, const workflow::Session& s, BrpOutput& out) {
  const bool locked =
      s.phase == Phase::kPlanLocked || s.phase == Phase::kAtTarget || s.phase == Phase::kDone;
  while ((p.remaining.front() == InputKind::kUnlockPlan && !locked) ||
         (p.remaining.front() == InputKind::kLockPlan && s.phase != Phase::kPlanning)) {
    p.remaining.pop_front();  // never the last: a check or an approval follows
  }
  const InputKind kind = p.remaining.front();
  p.remaining.pop_front();
  auto in = input(kind);
  switch (kind) {
    case InputKind::kCheckReady:
      in.path = p.phase == Workphase::kTargeting ? "targeting" : "robot";
      break;
    case InputKind::kApprove:
      if (!s.pending) {
        // No request to approve (stopped and resumed, say): ask for one, then approve it.
        p.remaining.push_front(InputKind::kApprove);
        in = input(InputKind::kRequestApproval);
        break;
      }
      in.plan_id = s.pending->plan_id;
      in.digest = s.pending->digest;
      break;
    default:
      break;
  }
  pending_[in.request_id] = std::move(p);
  out.inputs.push_back(std::move(in));
}

BrpOutput BrpBridge::onReply(const workflow::Reply& reply, const workflow::Session& s) {
  BrpOutput out;
  auto it = pending_.find(reply.request_id);
  if (it == pending_.end()) return out;
  Pending p = std::move(it->second);
  pending_.erase(it);
  const auto send = [&](Message msg) { out.messages.push_back({p.client, std::move(msg)}); };
  switch (p.purpose) {
    case Purpose::kCommand: {
      if (reply.accepted && !p.remaining.empty()) {
        dispatch(std::move(p), s, out);
        return out;
      }
      if (reply.accepted) last_accepted_ = p.phase;
      if (!brp2013()) reportCurrentStatus(p.client, s, out);
      const char* device = toString(p.phase);
      if (p.command) {
        // A COMMAND's answer is its RTS_COMMAND, whatever the revision.
        const auto& [id, name] = *p.command;
        if (!reply.accepted) {
          const Message refused = refusal(device, reply, p.phase, s);
          send(commandReply(id, name, false, reply.error_code, refused.status.status_string));
        } else if (p.phase == Workphase::kMoveToTarget && !options_.allow_motion_approval) {
          send(commandReply(id, name, true, "awaiting_approval",
                            fmt::format("waiting for an approver over DDS: {}",
                                        s.pending ? s.pending->summary : "no request")));
        } else {
          send(commandReply(id, name, true, "ok", reply.message));
        }
        return out;
      }
      if (!reply.accepted) {
        send(refusal(device, reply, p.phase, s));
      } else if (p.phase == Workphase::kMoveToTarget && !options_.allow_motion_approval) {
        // Released by an approver over DDS; the arrival is reported then.
        send(statusMessage(device, StatusCode::kNotReady,
                           fmt::format("waiting for an approver over DDS: {}",
                                       s.pending ? s.pending->summary : std::string("no request")),
                           "awaiting_approval"));
      } else if (p.phase != Workphase::kMoveToTarget &&
                 !(brp2013() &&
                   (p.phase == Workphase::kPlanning || p.phase == Workphase::kCalibration))) {
        // (brp2013: PLANNING has no result, CALIBRATION's follows the CLB_ transform.)
        send(statusMessage(device, StatusCode::kOk, reply.message));
      }
      // An approved move is answered when it arrives (onState).
      return out;
    }
    case Purpose::kCalibration:
      send(reply.accepted ? statusMessage("CALIBRATION", StatusCode::kOk, reply.message)
                          : refusal("CALIBRATION", reply, Workphase::kCalibration, s));
      return out;
    case Purpose::kTarget: {
      if (!reply.accepted) {
        send(refusal("TARGET", reply, Workphase::kTargeting, s));
        return out;
      }
      const auto t = std::find_if(s.targets.begin(), s.targets.end(),
                                  [&](const auto& x) { return x.id == reply.target_id; });
      if (t == s.targets.end()) return out;  // removed meanwhile by another client
      if (t->status() == "planned") {
        send(statusMessage("TARGET", StatusCode::kOk, t->message));
        const auto tip = s.robot->kinematics.forward(t->solution.joints).tip_mm;
        // The 2013 revision names it TARGET, the current Slicer module REACHABLE_TARGET.
        send(transformMessage(brp2013() ? "TARGET" : "REACHABLE_TARGET", poseRas(s, tip)));
        return out;
      }
      // The core judged it out of reach: it leaves the plan, and the reason goes back.
      auto in = input(InputKind::kRemoveTarget);
      in.ids.push_back(t->id);
      pending_[in.request_id] =
          pending(p.client, Purpose::kTargetRemoval, Workphase::kTargeting, t->message);
      out.inputs.push_back(std::move(in));
      return out;
    }
    case Purpose::kTargetRemoval:
      send(statusMessage("TARGET", StatusCode::kConfigurationError, p.why, "unreachable"));
      return out;
    case Purpose::kScan:
      if (!reply.accepted) {
        send(statusMessage(p.scan, statusCodeFor(reply.error_code, s.phase, options_.revision),
                           reply.message, errorNameFor(reply.error_code)));
        return out;
      }
      if (p.scan == kConfirmationScan && reply.job != 0) {
        measuring_[reply.job] = {p.client, p.scan_path};
      }
      send(statusMessage(p.scan, StatusCode::kOk, reply.message, "measuring"));
      return out;
    case Purpose::kOwnCommand: {
      const auto& [id, name] = *p.command;
      XmlAttributes more;
      if (reply.target_id != 0) more.emplace_back("TargetId", std::to_string(reply.target_id));
      if (reply.job != 0) more.emplace_back("Job", std::to_string(reply.job));
      send(commandReply(id, name, reply.accepted, reply.accepted ? "ok" : reply.error_code,
                        reply.message, more));
      return out;
    }
  }
  return out;
}

BrpOutput BrpBridge::onState(const workflow::Session& s) {
  BrpOutput out;
  reportMeasurements(s, out);  // asked for by the scan's sender, in either revision
  const Phase before = last_phase_;
  last_phase_ = s.phase;
  if (before == Phase::kMoving && s.phase != Phase::kMoving) {
    const auto& last = s.motions.empty() ? workflow::MotionRecord{} : s.motions.back();
    const bool halted_by_client = halt_asked_;
    halt_asked_ = false;
    if (s.phase == Phase::kAtTarget || s.phase == Phase::kDone) {
      out.messages.push_back(
          {0, statusMessage("MOVE_TO_TARGET", StatusCode::kOk,
                            last.target_id == 0
                                ? std::string("stylet retracted")
                                : fmt::format("arrived at target {}", last.target_id))});
      // Where it came to rest, after the result (the 2013 reference client waits for it).
      if (auto pose = tipToImageRas(s, s.position)) {
        out.messages.push_back({0, transformMessage("CURRENT_POSITION", *pose)});
      }
    } else if (!(brp2013() && halted_by_client && s.phase != Phase::kFault)) {
      // (brp2013: a STOP or EMERGENCY of the client's is answered by its own result alone.)
      const std::string why = s.phase == Phase::kFault ? s.fault : last.outcome;
      out.messages.push_back(
          {0, statusMessage("MOVE_TO_TARGET", statusCodeFor("", s.phase, options_.revision),
                            fmt::format("motion interrupted: {}", why.empty() ? "stop" : why),
                            s.phase == Phase::kStopped ? "stopped" : workflow::toString(s.phase))});
    }
  }
  // brp2013's robots say nothing unasked but the motion's result.
  if (brp2013()) return out;
  // Changes no command of ours asked for (a DDS client, the controller) are told to everyone.
  if (pending_.empty()) {
    Message status = currentStatus(s);
    const auto now = std::make_pair(workphase(s), status.status.code);
    if (last_reported_ && *last_reported_ != now) {
      last_reported_ = now;
      out.messages.insert(out.messages.begin(), {0, std::move(status)});
    } else if (!last_reported_) {
      last_reported_ = now;
    }
  }
  std::optional<Eigen::Matrix4d> registration;
  if (s.registration) registration = s.registration->imageToRobot() * rasFromLps();
  if (registration != last_registration_) {
    last_registration_ = registration;
    if (registration) out.messages.push_back({0, transformMessage("ImageToRobot", *registration)});
  }
  return out;
}

BrpOutput BrpBridge::onPosition(const workflow::Session& s, const actuation::Steps& live) const {
  BrpOutput out;
  if (auto pose = tipToImageRas(s, live)) {
    out.messages.push_back({0, transformMessage("CURRENT_POSITION", *pose)});
    if (!brp2013()) out.messages.push_back({0, transformMessage("NeedleTipToImage", *pose)});
  }
  return out;
}

void BrpBridge::annotate(Message& m, const workflow::Session& s) const {
  const auto set = [&](const char* key, std::string value) {
    for (auto& e : m.metadata) {
      if (e.key == key) return;  // what the message said for itself stands
    }
    m.metadata.push_back({key, kUsAscii, std::move(value)});
  };
  if (!s.robot_id.empty()) set("RobotId", s.robot_id);
  set("Workphase", toString(workphase(s)));
  if (m.type == "TRANSFORM" || m.type == "POINT" || m.type == "POLYDATA" || m.type == "TDATA" ||
      m.type == "IMAGE") {
    set("Units", "mm");
  }
}

Message imageFor(const std::string& name, const workflow::Session& s) {
  if (name == "PlanningCT" || name == kConfirmationScan) {
    const bool planning = name == "PlanningCT";
    const auto& volume = planning ? s.ct.volume : s.confirmation.ct;
    if (!volume) {
      return statusMessage(name, StatusCode::kNotReady,
                           planning ? "no CT is loaded"
                           : s.confirmation.source.empty()
                               ? "no confirmation CT has been measured"
                               : "the confirmation CT " + s.confirmation.source +
                                     " was measured before this server started: its voxels are "
                                     "in that file",
                           "no_volume");
    }
    Image image;
    image.size = volume->geometry.dims;
    image.scalar_type = ScalarType::kInt16;
    image.ijk_to_mm = rasFromLps() * volume->geometry.ijkToLps();
    // The CT's own voxels, shared: nothing is copied here (the listener's encoder copies once).
    image.data =
        std::shared_ptr<const char>(volume, reinterpret_cast<const char*>(volume->voxels.data()));
    image.data_bytes = volume->voxels.size() * sizeof(std::int16_t);
    image.value_scale = volume->value_scale;
    image.value_offset = volume->value_offset;
    Message m = imageMessage(name, std::move(image));
    m.metadata.push_back({"ValueUnits", kUsAscii, "HU"});
    m.metadata.push_back({"Source", kUsAscii, planning ? s.ct.source : s.confirmation.source});
    return m;
  }
  if (name == "Dose") {
    const auto* dose = s.dose.computed ? s.dose.computed->latest() : nullptr;
    if (!dose || !dose->dose_Gy) {
      return statusMessage(name, StatusCode::kNotReady, "no dose has been computed", "no_dose");
    }
    const auto& grid = s.dose.computed->grid;
    Image image;
    image.size = grid.dims;
    image.scalar_type = ScalarType::kFloat32;
    image.ijk_to_mm = rasFromLps() * grid.ijkToLps();
    image.data = std::shared_ptr<const char>(dose->dose_Gy,
                                             reinterpret_cast<const char*>(dose->dose_Gy->data()));
    image.data_bytes = dose->dose_Gy->size() * sizeof(float);
    Message m = imageMessage(name, std::move(image));
    m.metadata.push_back({"ValueUnits", kUsAscii, "Gy"});
    m.metadata.push_back({"Dose", kUsAscii, dose->what});
    return m;
  }
  return statusMessage(name, StatusCode::kNotFound, "images here: PlanningCT, ConfirmationCT, Dose",
                       "unknown_image");
}

Message plannedPaths(const workflow::Session& s) {
  const std::string device = "PlannedPaths";
  if (!s.registration) {
    return statusMessage(device, StatusCode::kNotReady, "not registered yet: no path is planned",
                         "not_registered");
  }
  PolyData p;
  PolyAttribute ids;
  ids.type = 0x00;  // per point (see the header)
  ids.name = "TargetId";
  const Eigen::Matrix3d to_ras = rasFromLps().topLeftCorner<3, 3>();
  std::vector<std::string> named;
  for (const auto& t : s.targets) {
    if (!t.registered || !t.solution.reachable()) continue;
    const auto path = workflow::needlePathLps(s, t.commandedJoints());
    if (path.size() < 2) continue;
    const auto first = static_cast<std::uint32_t>(p.points.size() / 3);
    p.lines.push_back(static_cast<std::uint32_t>(path.size()));
    for (std::size_t i = 0; i < path.size(); ++i) {
      const Eigen::Vector3d ras = to_ras * path[i];
      for (int a = 0; a < 3; ++a)
        p.points.push_back(static_cast<float>(ras[a]));
      p.lines.push_back(first + static_cast<std::uint32_t>(i));
      ids.values.push_back(static_cast<float>(t.id));
    }
    named.push_back(std::to_string(t.id));
  }
  p.attributes.push_back(std::move(ids));
  Message m = polyDataMessage(device, std::move(p));
  m.metadata.push_back({"Kind", kUsAscii, "paths"});
  std::string list;
  for (const auto& id : named)
    list += (list.empty() ? "" : " ") + id;
  m.metadata.push_back({"TargetIds", kUsAscii, list});
  return m;
}

std::string surfaceDeviceName(const std::string& name, const std::string& kind) {
  if (kind == "feasible") return "FeasibleVolume";
  if (kind == "isodose") {
    std::string digits;
    for (const char c : name) {
      if ((c >= '0' && c <= '9') || c == '.') digits += c;
    }
    return ("Isodose" + digits).substr(0, kMaxDeviceName);
  }
  return name.substr(0, kMaxDeviceName);
}

Message surfaceMessage(std::string device, const std::string& name, const std::string& kind,
                       const std::array<double, 3>& colour_rgb,
                       const std::vector<float>& points_lps,
                       const std::vector<std::uint32_t>& triangles) {
  PolyData p;
  p.points = points_lps;
  for (std::size_t i = 0; i + 2 < p.points.size(); i += 3) {  // LPS -> RAS: x and y negated
    p.points[i] = -p.points[i];
    p.points[i + 1] = -p.points[i + 1];
  }
  p.polygons.reserve(triangles.size() / 3 * 4);
  for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
    // LPS -> RAS is a half turn about S (determinant +1), not a mirror: the winding stays outward.
    p.polygons.insert(p.polygons.end(), {3, triangles[t], triangles[t + 1], triangles[t + 2]});
  }
  Message m = polyDataMessage(std::move(device), std::move(p));
  m.metadata.push_back({"Name", kUsAscii, name});
  m.metadata.push_back({"Kind", kUsAscii, kind});
  m.metadata.push_back(
      {"Colour", kUsAscii,
       fmt::format("{:.4g} {:.4g} {:.4g}", colour_rgb[0], colour_rgb[1], colour_rgb[2])});
  return m;
}

Message commandReply(std::uint32_t id, const std::string& name, bool success,
                     const std::string& code, const std::string& message,
                     const XmlAttributes& more) {
  XmlAttributes attributes{{"Name", name},
                           {"Status", success ? "SUCCESS" : "FAIL"},
                           {"Code", code},
                           {"Message", message}};
  attributes.insert(attributes.end(), more.begin(), more.end());
  return commandMessage("RTS_COMMAND", id, name, writeCommandXml("Command", attributes));
}

}  // namespace ignav::igtl
