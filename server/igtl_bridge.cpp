#include "igtl_bridge.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <utility>

namespace ignav::server {

using workflow::Input;

namespace {

// GET_POLYDATA's answer from the scene's surfaces: those named (all for "" or "Scene"), or why
// none.
igtl::BrpOutput surfaceAnswer(const igtl::SurfaceRequest& request,
                              const Expected<std::vector<protocol::SceneSurface>>& surfaces) {
  igtl::BrpOutput out;
  const auto tell = [&](igtl::Message m) {
    out.messages.push_back({request.client, std::move(m)});
  };
  const bool all = request.device.empty() || request.device == "Scene";
  if (!surfaces) {
    tell(igtl::statusMessage(all ? "Scene" : request.device, igtl::StatusCode::kBusy,
                             surfaces.error().message, "busy"));
    return out;
  }
  std::string names;
  for (const auto& surface : *surfaces) {
    const std::string device = igtl::surfaceDeviceName(surface.name, surface.kind);
    names += (names.empty() ? "" : ", ") + device;
    if (!all && device != request.device) continue;
    tell(igtl::surfaceMessage(device, surface.name, surface.kind, surface.colour_rgb,
                              surface.points_lps, surface.triangles));
  }
  if (!all && out.messages.empty()) {
    tell(igtl::statusMessage(request.device, igtl::StatusCode::kNotFound,
                             fmt::format("surfaces here now: {}; and PlannedPaths",
                                         names.empty() ? std::string("none") : names),
                             "unknown_surface"));
  }
  return out;
}

}  // namespace

std::unique_ptr<IgtlBridge> IgtlBridge::start(const OpenIgtlinkOptions& g,
                                              const std::filesystem::path& session_dir,
                                              std::function<void()> wake) {
  IgtlListenerOptions lo;
  lo.address = g.address;
  lo.port = g.port;
  lo.timeout_s = g.timeout_s;
  lo.tip_rate_hz = g.tip_rate_hz;
  lo.max_image_bytes = g.max_scan_mb << 20;
  auto listener = std::make_unique<IgtlListener>(lo, wake);
  auto port = listener->start();
  if (!port) {
    spdlog::error("{}; the server runs without OpenIGTLink", port.error().message);
    return nullptr;
  }
  auto scans = std::make_unique<ScanWriter>(session_dir / "received", wake);
  return std::unique_ptr<IgtlBridge>(
      new IgtlBridge(g, std::move(listener), *port, std::move(scans), std::move(wake)));
}

IgtlBridge::IgtlBridge(const OpenIgtlinkOptions& g, std::unique_ptr<IgtlListener> listener,
                       int port, std::unique_ptr<ScanWriter> scans, std::function<void()> wake)
    // Request ids never repeat across restarts (the core answers a repeated one from the journal).
    : bridge_(igtl::BrpOptions{g.allow_motion_approval,
                               igtl::parseRevision(g.protocol).value_or(igtl::Revision::kSlicer)},
              static_cast<std::uint64_t>(wallS() * 1e6)),
      tip_period_(std::chrono::duration_cast<Clock::duration>(
          std::chrono::duration<double>(1.0 / g.tip_rate_hz))),
      port_(port),
      scans_(std::move(scans)),
      listener_(std::move(listener)) {
  surfaces_->wake = std::move(wake);
  spdlog::info("OpenIGTLink (BRP workphase protocol, revision {}) listening on {}:{}", g.protocol,
               g.address, port_);
  if (g.allow_motion_approval) {
    safety_notice_ = fmt::format(
        "motion approval over OpenIGTLink is ON ({}:{}): OpenIGTLink is unauthenticated, so "
        "whoever can connect there can release motion",
        g.address, port_);
    spdlog::warn("!!! {} !!!", safety_notice_);
  }
}

IgtlBridge::~IgtlBridge() {
  std::lock_guard<std::mutex> lock(surfaces_->mutex);
  surfaces_->open = false;  // surfaces made after this wake nobody
}

void IgtlBridge::serve(const workflow::Session& session, const actuation::Steps& position,
                       const std::function<void(Input)>& run,
                       const std::function<void()>& clients_changed, std::size_t& handled) {
  // The inputs of one message (or one kept scan) run before the next is looked at.
  const auto runInputs = [&] {
    while (!inputs_.empty()) {
      Input in = std::move(inputs_.front());
      inputs_.pop_front();
      run(std::move(in));
    }
  };
  sendSurfaces(session);
  for (const auto& written : scans_->take()) {
    ++handled;
    send(bridge_.onScanSaved(written.scan, written.path, written.error), session);
    runInputs();
  }
  for (auto& ev : listener_->take()) {
    ++handled;
    switch (ev.kind) {
      case IgtlEvent::Kind::kConnected:
        send(bridge_.onConnected(ev.client, session), session);
        clients_changed();
        break;
      case IgtlEvent::Kind::kDisconnected:
        bridge_.onDisconnected(ev.client);
        spdlog::warn("OpenIGTLink client {} ({}) gone: {}", ev.client, ev.peer, ev.error);
        clients_changed();
        break;
      case IgtlEvent::Kind::kBadMessage:  // answered by the listener already
        spdlog::warn("OpenIGTLink client {} ({}): {}", ev.client, ev.peer, ev.error);
        break;
      case IgtlEvent::Kind::kMessage:
        // Queries may come many times a second: logged only when debugging.
        spdlog::log(
            ev.message.type.rfind("GET_", 0) == 0 ? spdlog::level::debug : spdlog::level::info,
            "OpenIGTLink client {}: {}({}, header v{}){}{}", ev.client, ev.message.type,
            ev.message.device_name, ev.message.header_version,
            ev.message.text.empty() ? "" : " \"" + ev.message.text.substr(0, 64) + "\"",
            ev.message.command.name.empty()
                ? ""
                : fmt::format(" #{} {}", ev.message.command.id, ev.message.command.name));
        send(bridge_.onMessage(ev.client, ev.message, session, position), session);
        break;
    }
    runInputs();
  }
}

void IgtlBridge::onState(const workflow::Session& session) {
  send(bridge_.onState(session), session);
}

void IgtlBridge::onPosition(const workflow::Session& session, const actuation::Steps& position) {
  send(bridge_.onPosition(session, position), session);
}

void IgtlBridge::onReading(const workflow::Session& session, const actuation::ControllerStatus& r,
                           const actuation::ControllerStatus& before, double measured_s) {
  const bool moving = r.state == actuation::ControllerState::kMoving;
  const bool was_moving = before.state == actuation::ControllerState::kMoving;
  if (listener_->clientCount() == 0 || !(moving || was_moving)) return;
  if (auto pose = igtl::tipToImageRas(session, r.position)) {
    listener_->publishTip(*pose, measured_s, moving);
  }
  if (r.position != last_steps_ &&
      (!moving || Clock::now() - last_position_ >= tip_period_ - tip_period_ / 10)) {
    last_position_ = Clock::now();
    last_steps_ = r.position;
    send(bridge_.onPosition(session, r.position), session);
  }
}

bool IgtlBridge::reply(const workflow::Reply& r, const workflow::Session& session) {
  if (r.client_id != igtl::kBridgeClientId) return false;
  if (!r.accepted) spdlog::warn("rejected (OpenIGTLink): {}", r.message);
  send(bridge_.onReply(r, session), session);
  return true;
}

void IgtlBridge::send(igtl::BrpOutput out, const workflow::Session& session) {
  const double now_s = wallS();  // the server's clock: what a protocol-3 client timestamps by
  for (auto& m : out.messages) {
    if (m.message.timestamp_s == 0) m.message.timestamp_s = now_s;
    bridge_.annotate(m.message, session);
    if (m.client == 0) {
      listener_->broadcast(std::move(m.message));
    } else {
      listener_->send(m.client, std::move(m.message));
    }
  }
  for (auto& in : out.inputs)
    inputs_.push_back(std::move(in));
  for (auto& request : out.surfaces) {
    if (!surface_source_) {
      igtl::BrpOutput none;
      none.messages.push_back(
          {request.client, igtl::statusMessage(request.device.empty() ? "Scene" : request.device,
                                               igtl::StatusCode::kNotReady,
                                               "this server makes no surfaces", "no_surfaces")});
      send(std::move(none), session);
      continue;
    }
    surface_source_([mailbox = surfaces_, request](auto made) {
      // On the slices thread: the meshes become messages there, not on the event thread.
      igtl::BrpOutput answer = surfaceAnswer(request, made);
      std::lock_guard<std::mutex> lock(mailbox->mutex);
      if (!mailbox->open) return;
      mailbox->made.push_back(std::move(answer));
      mailbox->wake();
    });
  }
  for (auto& scan : out.scans) {
    const std::uint64_t client = scan.client;
    const std::string device = scan.device;
    igtl::Message refused;
    if (read_only_) {
      refused = igtl::statusMessage(device, igtl::StatusCode::kNotReady,
                                    "this server replays a recorded session and takes no scans",
                                    "read_only");
    } else if (!scans_->write(std::move(scan))) {
      refused = igtl::statusMessage(
          device, igtl::StatusCode::kBusy,
          fmt::format("{} scans are being written already: send it again in a moment",
                      ScanWriter::kMaxWaiting),
          "busy");
    } else {
      continue;
    }
    refused.timestamp_s = now_s;
    bridge_.annotate(refused, session);
    listener_->send(client, std::move(refused));
  }
}

void IgtlBridge::sendSurfaces(const workflow::Session& session) {
  std::deque<igtl::BrpOutput> made;
  {
    std::lock_guard<std::mutex> lock(surfaces_->mutex);
    made.swap(surfaces_->made);
  }
  for (auto& out : made)
    send(std::move(out), session);
}

}  // namespace ignav::server
