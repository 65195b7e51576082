#include "confirmation_phantom.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>

#include <Eigen/Geometry>

#include <fmt/format.h>

#include "ignav/compensation/compensation.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/config/tissue_profiles.hpp"
#include "ignav/needle_world/rod_world.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/phantom.hpp"
#include "session_commands.hpp"

namespace ignav::plan {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The planning phantom's series takes its UIDs from seed 1; the confirmation scan's must differ
// from them whatever --seed is (another series of the same phantom, not the same one rewritten).
constexpr std::uint64_t kConfirmationUidSalt = 0x636f6e6669726dull;  // "confirm"
// How far the stylet is pushed on to see which way its tip goes (mm).
constexpr double kTangentStep_mm = 0.01;

// A new or empty folder we can write into; checked before anything is rendered.
void prepareOutDir(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir)) {
    throw CliError{dir + ": cannot make the output folder" +
                   (ec ? " (" + ec.message() + ")" : " (not a folder)")};
  }
  const auto entries = std::distance(fs::directory_iterator(dir, ec), fs::directory_iterator());
  if (entries > 0) {
    throw CliError{fmt::format(
        "{}: the output folder is not empty ({} entries): the new series would mix with what is "
        "there; give a new or empty folder",
        dir, entries)};
  }
  const fs::path probe = fs::path(dir) / ".ignav_write_probe";
  const bool writable = static_cast<bool>(std::ofstream(probe));
  fs::remove(probe, ec);
  if (!writable) throw CliError{dir + ": the output folder is not writable"};
}

// Beside the series, not in it: a DICOM reader would try the file (and DCMTK complain of it).
std::string defaultTruthPath(const std::string& out_dir) {
  fs::path dir = fs::path(out_dir).lexically_normal();
  if (dir.filename().empty()) dir = dir.parent_path();  // "ct/" is "ct"
  return dir.string() + "_truth.json";
}

struct Landed {
  Eigen::Vector3d tip_mm;
  Eigen::Vector3d direction;  // the stylet's tangent at the tip, unit, into the body
  Eigen::Vector3d seed_mm;    // where a seed is left (the tip, except where tissue drags)
  // The rod world's needle as it lies (cannula from the skin, then stylet); empty otherwise.
  std::vector<Eigen::Vector3d> cannula_mm, stylet_mm;
};

// An insertion's number in the rod world: the target and the joints (a second pass with other
// joints is another insertion, with its own luck).
std::uint64_t insertionOf(std::uint32_t id, const kinematics::Joints& j) {
  std::uint64_t h = id;
  for (double v : {j.theta_c_rad, j.z_c_mm, j.z_s_mm}) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &v, sizeof bits);
    h = (h ^ bits) * 0x100000001B3ull;
  }
  return h;
}

// Where the needle ends for these joints, in the robot frame: in the rod world, deflected by the
// hidden tissue, or the nominal forward kinematics without either. In the bicycle world its
// direction there is the way the tip goes when the stylet is pushed on a little (the same model,
// so the same deflection).
// `insertion` (0: these joints' own) names the try otherwise: an insertion stopped part-way and
// finished (as aimed, or re-aimed) is the same needle, with the luck of its first half.
Landed land(const kinematics::Kinematics& kinematics,
            const std::optional<compensation::DeflectionModel>& hidden,
            const std::optional<needle_world::RodWorld>& world, const kinematics::Joints& joints,
            std::uint32_t id, std::uint64_t insertion = 0) {
  if (world) {
    auto needle = needle_world::insertNeedle(*world, kinematics, joints,
                                             insertion != 0 ? insertion : insertionOf(id, joints));
    if (!needle) throw CliError{fmt::format("target {}: {}", id, needle.error().message)};
    return {needle->tip_mm, needle->direction, needle->seed_mm, needle->cannula_mm,
            needle->stylet_mm};
  }
  auto tip = [&](const kinematics::Joints& j) -> Eigen::Vector3d {
    if (!hidden) return kinematics.forward(j).tip_mm;
    auto landing = compensation::predictLanding(kinematics, *hidden, j);
    if (!landing) throw CliError{fmt::format("target {}: {}", id, landing.error().message)};
    return landing->tip_mm;
  };
  Landed out;
  out.tip_mm = tip(joints);
  kinematics::Joints further = joints;
  further.z_s_mm += kTangentStep_mm;
  const Eigen::Vector3d step = tip(further) - out.tip_mm;
  out.direction =
      step.norm() > 1e-9 ? step.normalized() : Eigen::Vector3d(-Eigen::Vector3d::UnitZ());
  out.seed_mm = out.tip_mm;
  return out;
}

json jointsJson(const kinematics::Joints& j) {
  return {{"theta_c_rad", j.theta_c_rad}, {"z_c_mm", j.z_c_mm}, {"z_s_mm", j.z_s_mm}};
}

}  // namespace

json confirmationPhantom(const ConfirmationPhantomArgs& args) {
  // The arguments first, then the session: a mistyped name costs no replay.
  std::optional<compensation::DeflectionModel> hidden;
  json hidden_json;  // null: no tissue, the needle lands on its nominal tip
  if (!args.hidden_tissue.empty()) {
    auto profiles = config::loadTissueProfiles(args.tissues_path);
    if (!profiles) throw CliError{profiles.error().message};
    auto profile = config::tissueProfile(*profiles, args.hidden_tissue);
    if (!profile) throw CliError{"--hidden-tissue: " + profile.error().message};
    hidden.emplace();
    hidden->needle = profile->needle;  // with the tissue's own curvature when it has one
    hidden->tissue = profile->tissue;
    hidden_json = {{"name", profile->name},
                   {"lambda1", profile->tissue.lambda1},
                   {"lambda2", profile->tissue.lambda2},
                   {"curvature_per_mm", profile->needle.curvature_per_mm},
                   {"wheelbase_mm", profile->needle.wheelbase_mm},
                   {"source", profile->source}};
  }
  std::optional<needle_world::RodWorld> world;
  if (!args.world_path.empty()) {
    if (hidden) throw CliError{"--world and --hidden-tissue: give one world, not both"};
    auto loaded = needle_world::loadRodWorld(args.world_path);
    if (!loaded) throw CliError{"--world: " + loaded.error().message};
    world = *loaded;
  }
  if (!(args.noise_hu >= 0.0) || !std::isfinite(args.noise_hu)) {
    throw CliError{fmt::format("--noise-hu: {} is not a noise SD (finite, ≥ 0 HU)", args.noise_hu)};
  }

  const workflow::Session session = replayedSession({args.session_dir, args.robot_path}).session;
  const config::Robot& robot = *session.robot;
  if (!session.registration) {
    throw CliError{args.session_dir +
                   ": the session was never registered: no target of it was placed in the robot's "
                   "frame, so there is no seed to deposit"};
  }
  // The reached targets, and one whose insertion stopped part-way (pause_at) when the scan is of
  // its needle there: an intermittent CT.
  std::vector<const workflow::Target*> reached;
  for (const auto& t : session.targets) {
    if (t.reached || (t.paused && t.id == args.needle_at)) reached.push_back(&t);
  }
  if (reached.empty()) {
    throw CliError{args.session_dir +
                   ": no target of this session was reached (or is stopped part-way at "
                   "--needle-at): there is no seed or needle to show"};
  }

  // The same phantom as the server's `phantom:` scan: the robot where it was, its markers too.
  auto rp = registration::makeRobotPhantom(robot.kinematics, robot.config.registration.scan);
  if (!rp) throw CliError{rp.error().message};
  volume::PhantomSpec spec = rp->spec;
  if (args.slice_mm != 0.0) {
    auto sliced = volume::withSliceSpacing(spec, args.slice_mm);
    if (!sliced) throw CliError{"--slice-mm: " + sliced.error().message};
    spec = *sliced;
  }
  spec.noise_sigma_hu = args.noise_hu;
  spec.seed = args.seed;
  const Eigen::Matrix4d robot_to_image_true = rp->image_to_robot_true.inverse();
  const Eigen::Matrix3d rotation_true = robot_to_image_true.topLeftCorner<3, 3>();
  const volume::Geometry grid = volume::phantomGeometry(spec);

  if (args.needle_at != 0 &&
      std::none_of(reached.begin(), reached.end(),
                   [&](const workflow::Target* t) { return t->id == args.needle_at; })) {
    throw CliError{
        fmt::format("--needle-at {}: no reached or paused target has that id", args.needle_at)};
  }
  json targets = json::array();
  double sum_mm = 0.0, max_mm = 0.0;
  std::size_t landed_count = 0;
  for (const workflow::Target* t : reached) {
    // The joints it was reached with, whatever the registration or the aim changed since; or
    // where its insertion stopped.
    const bool paused = !t->reached;
    const kinematics::Joints& joints = paused ? *t->paused : t->reached_joints;
    const std::uint64_t insertion = t->paused ? insertionOf(t->id, *t->paused) : 0;
    const Landed landed = land(robot.kinematics, hidden, world, joints, t->id, insertion);
    const bool needle = t->id == args.needle_at;
    // Where the scan shows it: the tip of a needle still in, else the seed it left.
    const Eigen::Vector3d landing_mm = needle ? landed.tip_mm : landed.seed_mm;
    volume::PhantomSeed seed;
    seed.centre_lps_mm = (robot_to_image_true * landing_mm.homogeneous()).head<3>();
    seed.axis_lps = rotation_true * landed.direction;
    const Eigen::Vector3d ijk = grid.toIjk(seed.centre_lps_mm);
    for (int a = 0; a < 3; ++a) {
      if (!(ijk[a] >= 0.0 && ijk[a] <= grid.dims[a] - 1)) {
        throw CliError{fmt::format(
            "target {}: its seed at LPS ({:.1f}, {:.1f}, {:.1f}) mm lies outside the scan "
            "({} x {} x {} voxels around LPS 0, 0, 0)",
            t->id, seed.centre_lps_mm.x(), seed.centre_lps_mm.y(), seed.centre_lps_mm.z(),
            grid.dims[0], grid.dims[1], grid.dims[2])};
      }
    }
    json needle_lps = json::array();  // the needle as drawn: cannula, then stylet
    if (needle) {
      // The needle as its world bends it (the straight push without one), from where it enters
      // the tissue (above it the robot holds it, and its markers lie on its axis).
      std::vector<Eigen::Vector3d> cannula_mm = landed.cannula_mm, stylet_mm = landed.stylet_mm;
      if (!world) {
        const compensation::DeflectionModel straight{{0.0, 20.0, -1}, {}, {}};
        auto path = compensation::predictPath(robot.kinematics, hidden ? *hidden : straight, joints,
                                              0.25, 0.0);
        if (!path) throw CliError{fmt::format("target {}: {}", t->id, path.error().message)};
        cannula_mm = path->cannula_mm;
        stylet_mm = path->stylet_mm;
      }
      auto toImage = [&](std::vector<Eigen::Vector3d> line) {
        for (auto& p : line)
          p = (robot_to_image_true * p.homogeneous()).head<3>();
        return line;
      };
      const auto& instrument = robot.kinematics.instrument();
      auto stylet = stylet_mm;
      stylet.insert(stylet.begin(), cannula_mm.back());
      volume::appendWire(spec, toImage(cannula_mm), instrument.cannula_outer_diameter_mm);
      volume::appendWire(spec, toImage(stylet), instrument.stylet_outer_diameter_mm);
      for (const auto& line : {toImage(cannula_mm), toImage(stylet_mm)})
        for (const auto& p : line)
          needle_lps.push_back(pointJson(p));
    } else {
      spec.seeds.push_back(seed);
    }
    const double off_mm = (landing_mm - t->robot_mm).norm();
    if (!paused) {  // a needle stopped part-way has not landed yet
      sum_mm += off_mm;
      max_mm = std::max(max_mm, off_mm);
      ++landed_count;
    }
    targets.push_back({{"id", t->id},
                       {"aimed_with", paused           ? "paused"
                                      : t->reaimed     ? "re-aimed"
                                      : t->compensated ? t->compensated->profile
                                                       : "nominal"},
                       {"joints", jointsJson(joints)},
                       {"planned_robot_mm", pointJson(t->robot_mm)},
                       {"landing_robot_mm", pointJson(landing_mm)},
                       {"tip_robot_mm", pointJson(landed.tip_mm)},
                       {"landing_lps_mm", pointJson(seed.centre_lps_mm)},
                       {"landing_kind", needle ? "tip" : "seed"},
                       {"needle_lps_mm", needle_lps},
                       {"seed_axis_lps", pointJson(seed.axis_lps)},
                       {"landing_off_plan_mm", off_mm}});
    if (paused) {
      // Where the insertion would land if it went on as aimed now: what a re-aim is judged by.
      const kinematics::Joints aimed = t->commandedJoints();
      const Landed finished = land(robot.kinematics, hidden, world, aimed, t->id, insertion);
      targets.back()["paused"] = true;
      targets.back()["aimed_joints"] = jointsJson(aimed);
      targets.back()["finished_landing_robot_mm"] = pointJson(finished.seed_mm);
      targets.back()["finished_off_plan_mm"] = (finished.seed_mm - t->robot_mm).norm();
    }
  }

  const std::string truth_path =
      args.truth_path.empty() ? defaultTruthPath(args.out_dir) : args.truth_path;
  prepareOutDir(args.out_dir);
  if (!std::ofstream(truth_path, std::ios::app)) {
    throw CliError{truth_path + ": cannot write the truth file"};
  }
  auto ct = volume::makePhantom(spec);
  if (!ct) throw CliError{ct.error().message};
  volume::DicomWriteOptions options;
  options.seed = args.seed ^ kConfirmationUidSalt;
  options.series_description = "ignav confirmation phantom";
  auto files = volume::writeDicomSeries(*ct, args.out_dir, options);
  if (!files) throw CliError{files.error().message};

  const auto& g = ct->geometry;
  json truth = {{"session", args.session_dir},
                {"session_id", session.session_id},
                {"robot", robot.config.name},
                {"hidden_tissue", hidden_json},
                {"world", world ? json{{"kind", "rod_in_tissue"},
                                       {"name", world->name},
                                       {"source", world->source},
                                       {"file", args.world_path},
                                       {"seed", world->seed}}
                                : json()},
                {"session_tissue", session.tissue ? json(session.tissue->name) : json()},
                {"image_to_robot_true", matrixRowsJson(rp->image_to_robot_true)},
                {"ct",
                 {{"dims", {g.dims[0], g.dims[1], g.dims[2]}},
                  {"spacing_mm", pointJson(g.spacing_mm)},
                  {"noise_hu", spec.noise_sigma_hu},
                  {"seed_psf_sigma_mm", spec.seed_psf_sigma_mm},
                  {"seed", spec.seed},
                  {"markers_lps_mm", json::array()}}},
                {"targets", targets},
                {"landing_off_plan_mm",
                 {{"mean", landed_count ? sum_mm / static_cast<double>(landed_count) : 0.0},
                  {"max", max_mm}}}};
  for (const auto& m : spec.fiducials_lps_mm)
    truth["ct"]["markers_lps_mm"].push_back(pointJson(m));
  std::ofstream out(truth_path, std::ios::trunc);
  out << truth.dump(2) << "\n";
  if (!out) throw CliError{truth_path + ": cannot write the truth file"};
  truth["out_dir"] = args.out_dir;
  truth["files"] = files->size();
  truth["truth_path"] = truth_path;
  return truth;
}

std::string confirmationPhantomText(const json& truth) {
  const json& ct = truth["ct"];
  const auto needles = static_cast<std::size_t>(
      std::count_if(truth["targets"].begin(), truth["targets"].end(),
                    [](const json& t) { return t.value("landing_kind", "seed") == "tip"; }));
  std::string out = fmt::format(
      "confirmation phantom: {} seeds{} in {} x {} x {} voxels of {:.2f} x {:.2f} x {:.2f} mm, "
      "noise {:g} HU -> {}\n",
      truth["targets"].size() - needles, needles != 0 ? " and a needle left in" : "",
      ct["dims"][0].get<int>(), ct["dims"][1].get<int>(), ct["dims"][2].get<int>(),
      ct["spacing_mm"][0].get<double>(), ct["spacing_mm"][1].get<double>(),
      ct["spacing_mm"][2].get<double>(), ct["noise_hu"].get<double>(),
      truth["out_dir"].get<std::string>());
  const json& tissue = truth["hidden_tissue"];
  const json& world = truth["world"];
  out += !world.is_null()
             ? fmt::format(
                   "world {} (rod in tissue, {}): physics the server does not model; the "
                   "session's own profile: {}\n",
                   world["name"].get<std::string>(), world["file"].get<std::string>(),
                   truth["session_tissue"].is_null() ? std::string("none")
                                                     : truth["session_tissue"].get<std::string>())
         : tissue.is_null()
             ? std::string("no hidden tissue: each seed lies at its joints' nominal tip\n")
             : fmt::format("hidden tissue {} (λ1 {:g}, λ2 {:g}); the session's own profile: {}\n",
                           tissue["name"].get<std::string>(), tissue["lambda1"].get<double>(),
                           tissue["lambda2"].get<double>(),
                           truth["session_tissue"].is_null()
                               ? std::string("none")
                               : truth["session_tissue"].get<std::string>());
  out += fmt::format("the truth: {}\n\n{:>4}  {:>10}  {:>26}  {:>26}  {:>8}\n",
                     truth["truth_path"].get<std::string>(), "id", "aimed", "planned (robot mm)",
                     "landing (robot mm)", "off mm");
  auto p3 = [](const json& p) {
    return fmt::format("({:7.2f},{:7.2f},{:7.2f})", p[0].get<double>(), p[1].get<double>(),
                       p[2].get<double>());
  };
  for (const auto& t : truth["targets"]) {
    out += fmt::format("{:>4}  {:>10}  {:>26}  {:>26}  {:8.2f}\n", t["id"].get<unsigned>(),
                       t["aimed_with"].get<std::string>(), p3(t["planned_robot_mm"]),
                       p3(t["landing_robot_mm"]), t["landing_off_plan_mm"].get<double>());
  }
  return out;
}

}  // namespace ignav::plan
