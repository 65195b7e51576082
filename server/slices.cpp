#include "slices.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <exception>
#include <utility>

#include "ignav/volume/render.hpp"
#include "ignav/volume/slice.hpp"
#include "reports.hpp"

namespace ignav::server {

using namespace ignav::protocol;

Slices::Slices(const Participant& participant)
    : replies_(participant), scene_replies_(participant), thread_([this] { loop(); }) {}

Slices::~Slices() {
  std::deque<Job> left;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    left.swap(queue_);
  }
  wake_.notify_one();
  thread_.join();
  for (const auto& job : left) {
    try {
      refuse(job, "not drawn: the server is stopping");
    } catch (const std::exception& e) {
      spdlog::warn("slices: {}", e.what());
    }
  }
  spdlog::info("slices: {} drawn, {} refused (queue full), {} left at shutdown", done_, refused_,
               left.size());
}

void Slices::surfaces(Snapshot session, SurfacesDone done) {
  Job job;
  job.session = std::move(session);
  job.client_id = "openigtlink";
  job.surfaces_done = std::move(done);
  enqueue(std::move(job));
}

void Slices::request(const SliceRequest& r, Snapshot session) {
  Job job;
  job.session = std::move(session);
  job.client_id = r.client_id;
  job.view = r.view;
  job.request_id = r.request_id;
  job.centre_lps = toEigen(r.centre_lps);
  job.size_px = r.size_px;
  job.pixel_mm = r.pixel_mm;
  job.window = r.window;
  job.level = r.level;
  job.overlays = r.overlays;
  job.region_only = r.region_only;
  enqueue(std::move(job));
}

void Slices::request(const SceneRequest& r, Snapshot session) {
  Job job;
  job.session = std::move(session);
  job.client_id = r.client_id;
  job.request_id = r.request_id;
  job.scene = r;
  enqueue(std::move(job));
}

void Slices::enqueue(Job job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (queue_.size() < kMaxQueued) {
      queue_.push_back(std::move(job));
      wake_.notify_one();
      return;
    }
    ++refused_;
  }
  // Full: the newest is refused, so that those who asked first get theirs.
  refuse(job, fmt::format("busy: {} slice and scene requests are waiting to be drawn; ask again",
                          kMaxQueued));
}

void Slices::loop() {
  for (;;) {
    Job job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;  // the destructor answers what is left
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    // A slice that cannot be drawn or sent is said in the log; it never stops the server.
    try {
      if (job.surfaces_done) {
        job.surfaces_done(scene_.surfaces(*job.session));
      } else if (job.scene) {
        scene_replies_.write(scene_.build(*job.scene, *job.session));
      } else {
        Result result = render(job);
        send(result);
      }
    } catch (const std::exception& e) {
      spdlog::error("slices: request {} from '{}': {}", job.request_id, job.client_id, e.what());
    }
    std::lock_guard<std::mutex> lock(mutex_);
    ++done_;
  }
}

Slices::Result Slices::render(const Job& req) {
  Result out;
  out.client_id = req.client_id;
  out.request_id = req.request_id;
  auto fail = [&](const std::string& why) {
    out.message = why;
    return out;
  };
  const workflow::Session& session = *req.session;
  if (!session.ct.volume) return fail("no CT is loaded");
  volume::SliceSpec spec;
  if (req.view == "axial") {
    spec.view = volume::View::kAxial;
  } else if (req.view == "coronal") {
    spec.view = volume::View::kCoronal;
  } else if (req.view == "sagittal") {
    spec.view = volume::View::kSagittal;
  } else {
    return fail("view '" + req.view + "' is not axial, coronal or sagittal");
  }
  if (!req.centre_lps.allFinite() || !std::isfinite(req.pixel_mm) || !std::isfinite(req.window) ||
      !std::isfinite(req.level)) {
    return fail("centre_lps, pixel_mm, window and level must be finite");
  }
  if (req.size_px > 2048) return fail(fmt::format("size_px {} exceeds 2048", req.size_px));
  spec.centre_lps_mm = req.centre_lps;
  spec.width_px = spec.height_px = static_cast<int>(req.size_px);
  spec.pixel_size_mm = req.pixel_mm;
  spec.window = volume::kWindowBone;
  if (req.window > 0.0) spec.window = {req.window, req.level};
  auto slice = volume::reslice(*session.ct.volume, spec);
  if (!slice) return fail(slice.error().message);
  volume::Overlays overlays;
  if (req.overlays) overlays = overlaysFor(session);
  if (req.overlays && req.region_only) {
    overlays.points.clear();
    overlays.paths.clear();
  }
  auto png = renderer_.renderPng(*slice, overlays);
  if (!png) return fail(png.error().message);
  out.ok = true;
  out.width = static_cast<std::uint32_t>(slice->width);
  out.height = static_cast<std::uint32_t>(slice->height);
  out.pixel_to_lps = slice->pixel_to_lps;
  out.png = std::move(png).value();
  return out;
}

void Slices::refuse(const Job& job, const std::string& why) const {
  if (job.surfaces_done) {
    job.surfaces_done(makeError(ErrorCode::kIo, why, "busy"));
    return;
  }
  if (job.scene) {
    SceneReply r;
    r.client_id = job.client_id;
    r.request_id = job.request_id;
    r.part = job.scene->part;
    r.message = why;
    scene_replies_.write(r);
    return;
  }
  Result out;
  out.client_id = job.client_id;
  out.request_id = job.request_id;
  out.message = why;
  send(out);
}

void Slices::send(Result& s) const {
  SliceReply r;
  r.client_id = std::move(s.client_id);
  r.request_id = s.request_id;
  r.ok = s.ok;
  r.message = std::move(s.message);
  r.width = s.width;
  r.height = s.height;
  r.pixel_to_lps = toRowMajor(s.pixel_to_lps);
  r.png = std::move(s.png);
  replies_.write(r);
}

}  // namespace ignav::server
