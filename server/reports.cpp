#include "reports.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <fstream>
#include <memory>
#include <mutex>
#include <utility>

#include <Eigen/Geometry>

#include "ignav/dosimetry/isodose.hpp"
#include "ignav/kinematics/reachable_region.hpp"
#include "ignav/kinematics/workspace_map.hpp"
#include "ignav/registration/slicer_export.hpp"
#include "ignav/verification/targeting_report.hpp"
#include "ignav/volume/slice.hpp"
#include "ignav/workflow/reducer.hpp"

namespace ignav::server {
namespace {

namespace fs = std::filesystem;
using workflow::Session;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

// Written aside and renamed over: a reader never meets a half-written (or empty) file.
bool writeAtomically(const fs::path& path, const char* data, std::size_t size) {
  const fs::path aside = path.string() + ".tmp";
  {
    std::ofstream out(aside, std::ios::binary | std::ios::trunc);
    out.write(data, static_cast<std::streamsize>(size));
    if (!out) {
      spdlog::warn("{}: not written", aside.string());
      return false;
    }
  }
  std::error_code ec;
  fs::rename(aside, path, ec);
  if (ec) spdlog::warn("{}: not updated: {}", path.string(), ec.message());
  return !ec;
}

// The robot's ReachableRegion, made once (its table takes ~16k inverse solves, ~7 ms) and
// kept while the robot is; the slices and reports threads share it.
std::shared_ptr<const kinematics::ReachableRegion> reachableRegionOf(
    const std::shared_ptr<const config::Robot>& robot) {
  static std::mutex mutex;
  static std::weak_ptr<const config::Robot> cached_robot;
  static std::shared_ptr<const kinematics::ReachableRegion> cached;
  const std::lock_guard<std::mutex> lock(mutex);
  if (!cached || cached_robot.lock() != robot) {
    cached = std::make_shared<const kinematics::ReachableRegion>(robot->kinematics);
    cached_robot = robot;
  }
  return cached;
}

}  // namespace

volume::Overlays overlaysFor(const Session& session) {
  volume::Overlays o;
  if (const auto& reg = session.registration) {
    for (std::size_t i = 0; i < reg->image_mm.size(); ++i) {
      o.points.push_back({reg->image_mm[i], "F" + std::to_string(i + 1), {255, 255, 0}, 4});
    }
    const auto region = reachableRegionOf(session.robot);
    const registration::Registration r = *reg;
    std::vector<Eigen::Vector3d> bounds;
    for (const Eigen::Vector3d& corner : region->boundingBox())
      bounds.push_back(r.toImage(corner));
    o.regions.push_back(
        {[region, r](const Eigen::Vector3d& lps) { return region->contains(r.toRobot(lps)); },
         std::move(bounds),
         {},
         {0, 200, 80},
         0.25});
  }
  // The patient's structures as outlines in their colours (issue 41).
  if (const auto set = session.structures.loaded.set) {
    for (std::size_t n = 0; n < set->structures.size(); ++n) {
      const auto& mask = set->structures[n].mask;
      const auto cubes = mask.corners(0.5);
      const Eigen::Matrix4d to_ijk = mask.geometry.lpsToIjk();
      const auto& rgb = set->structures[n].colour_rgb;
      auto channel = [](double c) { return static_cast<std::uint8_t>(std::lround(255.0 * c)); };
      o.regions.push_back({[set, n, to_ijk](const Eigen::Vector3d& lps) {
                             return set->structures[n].mask.insideNearest(
                                 (to_ijk * lps.homogeneous()).head<3>());
                           },
                           {cubes.begin(), cubes.end()},
                           {},
                           {channel(rgb[0]), channel(rgb[1]), channel(rgb[2])},
                           1.0,
                           true,
                           set->structures[n].name});
    }
  }
  // The seeds' isodose lines (issue 42): the delivered dose's once a confirmation CT found seeds,
  // else the planned.
  if (const auto& dose = session.dose.computed) {
    if (const auto* latest = dose->latest()) {
      for (auto& line :
           dosimetry::isodoseOverlays(latest->dose_Gy, dose->grid, dose->seeds.prescription_Gy))
        o.regions.push_back(std::move(line));
    }
  }
  for (const auto& t : session.targets) {
    const volume::Rgb colour = !t.registered   ? volume::Rgb{160, 160, 160}
                               : t.plannable() ? volume::Rgb{0, 255, 0}
                                               : volume::Rgb{255, 60, 60};
    o.points.push_back({t.lps_mm, "T" + std::to_string(t.id), colour, 5});
  }
  return o;
}

Reports::Reports(fs::path session_dir)
    : session_dir_(std::move(session_dir)), thread_([this] { loop(); }) {}

Reports::~Reports() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  thread_.join();
  spdlog::info("reports: {} jobs done ({} replaced by newer ones before they ran)", done_,
               replaced_);
}

void Reports::exports(Snapshot session) {
  submit({Kind::kExports, std::move(session), false, 0});
}

void Reports::report(Snapshot session) {
  submit({Kind::kReport, std::move(session), false, 0});
}

void Reports::slices(Snapshot session, bool all_targets, std::uint32_t reached_id) {
  submit({Kind::kSlices, std::move(session), all_targets, reached_id});
}

void Reports::verification(Snapshot session) {
  submit({Kind::kVerification, std::move(session), false, 0});
}

void Reports::submit(Job job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    // What the new job makes useless: an older job of its kind (the slices through a reached
    // target only when the new one is a lock's, which starts the pictures afresh). The new job
    // goes last, so the report always comes after the slices it lists.
    const auto size = queue_.size();
    queue_.erase(std::remove_if(queue_.begin(), queue_.end(),
                                [&](const Job& queued) {
                                  return queued.kind == job.kind &&
                                         (job.kind != Kind::kSlices || job.all_targets);
                                }),
                 queue_.end());
    replaced_ += size - queue_.size();
    queue_.push_back(std::move(job));
  }
  wake_.notify_one();
}

void Reports::loop() {
  for (;;) {
    Job job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, and everything handed over is written
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    run(job);
    std::lock_guard<std::mutex> lock(mutex_);
    ++done_;
  }
}

void Reports::run(const Job& job) {
  // A file for people that cannot be written is said in the log; it never stops the server.
  try {
    switch (job.kind) {
      case Kind::kExports:
        writeExports(*job.session);
        break;
      case Kind::kReport:
        writeReport(*job.session);
        break;
      case Kind::kSlices:
        writeSlices(*job.session, job.all_targets, job.reached_id);
        break;
      case Kind::kVerification:
        writeVerification(*job.session);
        break;
    }
  } catch (const std::exception& e) {
    spdlog::error("reports: {}", e.what());
  }
}

void Reports::writeExports(const Session& session) {
  if (session.registration) {
    const auto& reg = *session.registration;
    (void)registration::writeItkTransform(reg, (session_dir_ / "image_to_robot.tfm").string());
    std::vector<registration::MarkupPoint> fiducials;
    for (std::size_t i = 0; i < reg.image_mm.size() && i < 3; ++i) {
      fiducials.push_back({registration::toString(static_cast<registration::FeaturePoint>(i)),
                           reg.image_mm[i], fmt::format("residual {:.3f} mm", reg.residuals_mm[i]),
                           true});
    }
    (void)registration::writeMarkupsJson("ignav fiducials", fiducials,
                                         (session_dir_ / "fiducials.mrk.json").string());
  }
  std::vector<registration::MarkupPoint> targets;
  for (const auto& t : session.targets) {
    targets.push_back({"T" + std::to_string(t.id), t.lps_mm, t.message, false});
  }
  (void)registration::writeMarkupsJson("ignav targets", targets,
                                       (session_dir_ / "targets.mrk.json").string());
  // Targets proposed to fill a structure and not yet accepted, for Slicer beside the plan's.
  const auto& proposals = session.proposals;
  if (proposals.status == "proposed" || fs::exists(session_dir_ / "proposed_targets.mrk.json")) {
    std::vector<registration::MarkupPoint> proposed;
    for (const auto& p : proposals.targets)
      proposed.push_back({"P" + std::to_string(p.id), p.lps_mm,
                          fmt::format("proposed to fill '{}' at {:g} mm", proposals.structure,
                                      proposals.spacing_mm),
                          false});
    (void)registration::writeMarkupsJson("ignav proposed targets", proposed,
                                         (session_dir_ / "proposed_targets.mrk.json").string());
  }
  // Where to mount the robot, for Slicer: the best pose as a transform (robot-frame data under it,
  // such as feasible_volume.ply, shows where the robot would reach) and every pose's entry point.
  const auto& placed = session.robot_placement;
  if (placed.status == "placed" && !placed.poses.empty() && session.robot) {
    const Eigen::Matrix4d image_to_robot = placed.poses.front().pose.imageToRobot();
    registration::Registration as_registration;
    as_registration.kind = registration::TransformKind::kRigid;
    as_registration.rotation = image_to_robot.topLeftCorner<3, 3>();
    as_registration.translation_mm = image_to_robot.topRightCorner<3, 1>();
    (void)registration::writeItkTransform(as_registration,
                                          (session_dir_ / "robot_placement.tfm").string());
    std::vector<registration::MarkupPoint> entries;
    for (std::size_t n = 0; n < placed.poses.size(); ++n) {
      const auto& p = placed.poses[n];
      entries.push_back(
          {fmt::format("{} {:.1f} %", n == 0 ? "entry" : "alt " + std::to_string(n),
                       100.0 * p.coverage.fraction()),
           p.skin.entry_lps_mm,
           fmt::format("covers {:.1f} % of '{}'; axis ({:.3f}, {:.3f}, {:.3f}) LPS, tilt {:.1f}°",
                       100.0 * p.coverage.fraction(), placed.structure, p.pose.insertion().x(),
                       p.pose.insertion().y(), p.pose.insertion().z(), p.tilt_deg),
           n == 0});
    }
    (void)registration::writeMarkupsJson("ignav robot placement", entries,
                                         (session_dir_ / "robot_placement.mrk.json").string());
    const auto ply = session_dir_ / "feasible_volume.ply";
    if (!fs::exists(ply)) {
      if (auto map = kinematics::computeWorkspaceMap(session.robot->kinematics, 1.0))
        (void)kinematics::writeWorkspacePly(*map, ply.string());
    }
  }
  // The structures as the plan used them, roles included (Slicer keeps them as segment tags).
  const auto& st = session.structures;
  const bool same_roles = st.roles.size() == exported_roles_.size() &&
                          std::equal(st.roles.begin(), st.roles.end(), exported_roles_.begin(),
                                     [](const auto& a, const auto& b) {
                                       return a.role == b.role && a.margin_mm == b.margin_mm;
                                     });
  if (st.loaded.set && session.ct.volume &&
      (st.loaded.set != exported_structures_ || !same_roles)) {
    anatomy::StructureSet used = *st.loaded.set;
    for (std::size_t n = 0; n < used.structures.size() && n < st.roles.size(); ++n) {
      used.structures[n].role = st.roles[n].role;
      used.structures[n].margin_mm = st.roles[n].margin_mm;
    }
    const auto written = anatomy::writeSegNrrd(used, session.ct.volume->geometry,
                                               (session_dir_ / "structures.seg.nrrd").string());
    if (!written.ok()) spdlog::warn("reports: {}", written.error().message);
    exported_structures_ = st.loaded.set;
    exported_roles_ = st.roles;
  }
}

void Reports::writeVerification(const Session& session) const {
  const auto& c = session.confirmation;
  if (!c.targets.empty() || !c.seeds.empty()) {
    const fs::path dir = session_dir_ / "verification";
    std::error_code ec;
    fs::create_directories(dir, ec);
    std::vector<registration::MarkupPoint> seeds;
    for (const auto& seed : c.seeds) {
      if (seed.rejected) continue;
      std::string label = "seed " + std::to_string(seed.id);
      std::string description = seed.placed ? "placed by hand" : "detected";
      for (const auto& t : c.targets) {
        if (t.seed_id != seed.id || !c.rowsAreThisScans()) continue;
        label = "T" + std::to_string(t.error.target_id);
        description +=
            fmt::format("; {:.2f} mm from target {}", t.error.error_mm, t.error.target_id);
      }
      seeds.push_back({label, seed.lps_mm, description, true});
    }
    // On the confirmation CT's LPS: open it with that scan.
    (void)registration::writeMarkupsJson("ignav seeds (" + c.source + ")", seeds,
                                         (dir / "seeds.mrk.json").string());
    std::vector<verification::TargetError> errors;
    for (const auto& t : c.targets)
      errors.push_back(t.error);
    verification::FigureOptions options;
    options.title =
        "session " + session.session_id + ": " + (c.rows_source.empty() ? c.source : c.rows_source);
    const auto png = verification::targetingFigurePng(
        errors, c.summary.value_or(verification::ErrorSummary{}),
        verification::feasibleVolume(session.robot->kinematics), options);
    if (png) {
      (void)volume::writePng(*png, (dir / "targeting.png").string());
    } else {
      spdlog::error("reports: the targeting figure: {}", png.error().message);
    }
  }
  if (session.fitted_tissues.empty()) {
    std::error_code ec;  // the last fit was discarded (discard_tissue): nothing to offer
    std::filesystem::remove(session_dir_ / "tissues_fitted.yaml", ec);
  } else {
    const auto& needle = session.fitted_tissues.front().profile.needle;
    std::string yaml = fmt::format(
        "# Tissues fitted from the measured targeting errors of session {} (fit_tissue).\n"
        "# A configs/tissues.yaml: use it as server.yaml tissue.profiles, or copy an entry.\n"
        "needle:\n  curvature_per_mm: {}\n  wheelbase_mm: {}\ntissues:\n",
        session.session_id, needle.curvature_per_mm, needle.wheelbase_mm);
    for (const auto& f : session.fitted_tissues)
      yaml += f.yaml;
    writeAtomically(session_dir_ / "tissues_fitted.yaml", yaml.data(), yaml.size());
  }
}

void Reports::writeReport(const Session& session) const {
  std::vector<std::string> images;
  for (const auto& [id, files] : images_)
    images.insert(images.end(), files.begin(), files.end());
  const std::string text = workflow::procedureReport(session, images);
  writeAtomically(session_dir_ / "report.md", text.data(), text.size());
}

void Reports::writeSlices(const Session& session, bool all_targets, std::uint32_t reached_id) {
  constexpr std::size_t kReportTargets = 12;
  if (all_targets) images_.clear();  // a lock starts the pictures afresh
  if (!session.ct.volume || !session.registration) return;
  const auto started = Clock::now();
  const fs::path dir = session_dir_ / "report";
  std::error_code ec;
  fs::create_directories(dir, ec);
  std::size_t drawn = 0;
  for (const auto& t : session.targets) {
    if (!t.plannable()) continue;
    if (!all_targets && t.id != reached_id) continue;
    if (all_targets && ++drawn > kReportTargets) break;
    volume::Overlays overlays = overlaysFor(session);
    overlays.paths.push_back(
        {workflow::needlePathLps(session, t.commandedJoints()), {0, 255, 255}, 1});
    if (t.reached) {
      const auto& robot = *session.robot;
      const Eigen::Vector3d tip =
          robot.kinematics.forward(robot.transmission.toJoints(session.position)).tip_mm;
      overlays.points.push_back({session.registration->toImage(tip), "tip", {255, 0, 255}, 3});
    }
    std::vector<std::string> files;
    for (const auto& [view, name] :
         {std::pair{volume::View::kCoronal, "coronal"}, std::pair{volume::View::kAxial, "axial"}}) {
      volume::SliceSpec spec;
      spec.view = view;
      spec.centre_lps_mm = t.lps_mm;
      spec.width_px = spec.height_px = 384;
      spec.pixel_size_mm = 0.2;
      spec.window = volume::kWindowBone;
      auto slice = volume::reslice(*session.ct.volume, spec);
      if (!slice) continue;
      auto png = volume::renderPng(*slice, overlays);
      if (!png) continue;
      const std::string file =
          fmt::format("report/T{}_{}{}.png", t.id, name, t.reached ? "_reached" : "");
      if (!writeAtomically(session_dir_ / file, reinterpret_cast<const char*>(png->data()),
                           png->size())) {
        continue;
      }
      files.push_back(file);
    }
    images_[t.id] = files;
  }
  // On the reports thread: the event loop goes on meanwhile (docs/ARCHITECTURE.md).
  spdlog::info("report slices written in {:.0f} ms", msSince(started));
}

}  // namespace ignav::server
