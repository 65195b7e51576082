// The patient's structures in the reducer (issue 41), without DDS: the built-in phantom's anatomy
// loaded through its job, a target whose needle crosses the urethra refused by name with the
// closest approach the closed form gives, lock_plan refusing it, an operator's override with a
// reason in the approval request, roles changed by command, and bad input leaving the session
// as it was.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <set>

#include <fmt/format.h>

#include "ignav/anatomy/dicom_structures.hpp"
#include "ignav/anatomy/structures.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/reducer.hpp"
#include "workflow/bench.hpp"

namespace ignav::workflow {
namespace {

using rig::Bench;
using test::paperRobot;

Input withText(Bench& b, InputKind kind, const std::string& text,
               std::vector<std::uint32_t> ids = {}) {
  Input in = b.command(kind, {}, std::move(ids));
  in.path = text;
  return in;
}

// A command that starts a job, then that job run here as the server's job thread would, its
// outcome fed back.
Reply sendAndRunJob(Bench& b, InputKind command, const std::string& text, JobKind kind) {
  const Reply started = b.send(withText(b, command, text));
  if (!started.accepted) return started;
  for (const auto& job : pendingJobs(b.s)) {
    if (job.kind == kind) b.feed(job.run({}));
  }
  return started;
}

Reply loadStructures(Bench& b, const std::string& source) {
  return sendAndRunJob(b, InputKind::kLoadStructures, source, JobKind::kStructureLoad);
}

// The urethra of the phantom (phantom_anatomy.cpp): a 3 mm cylinder parallel to the robot's
// axis at x = 0.55 r_max. The needle's surface from it along the whole centreline, in closed
// form: the distance of each point from the axis, less the radii.
double urethraClearance(const kinematics::Joints& j) {
  const auto& kin = paperRobot()->kinematics;
  const auto line = kin.centreline(j, 0.01);
  const Eigen::Vector2d axis(0.55 * kin.maxRadius_mm(), 0.0);
  double best = 1e9;
  const auto& in = kin.instrument();
  for (const auto& p : line.cannula_mm)
    best = std::min(best, (p.head<2>() - axis).norm() - 3.0 - 0.5 * in.cannula_outer_diameter_mm);
  for (const auto& p : line.stylet_mm)
    best = std::min(best, (p.head<2>() - axis).norm() - 3.0 - 0.5 * in.stylet_outer_diameter_mm);
  return best;
}

// Joints whose tip lies at this radius and depth in the direction of +x (towards the urethra) or
// -x (away from it).
kinematics::Joints jointsTowards(double x_mm, double z_mm) {
  return paperRobot()->kinematics.inverse(Eigen::Vector3d(x_mm, 0.0, z_mm)).value().joints;
}

TEST(Structures, ANeedleCrossingTheUrethraIsRefusedUntilAnOperatorOverridesIt) {
  Bench b;
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  ASSERT_EQ(b.s.structures.status, "loaded") << b.s.structures.message;
  ASSERT_EQ(b.s.structures.loaded.set->structures.size(), 4u);
  const auto& kin = paperRobot()->kinematics;
  const double r_max = kin.maxRadius_mm();
  const double z = kin.tipDepthAtHome_mm(0.8 * kin.instrument().stylet_travel_mm) - 15.0;
  const auto crossing = jointsTowards(0.85 * r_max, z);
  const auto clear = jointsTowards(-0.85 * r_max, z);
  const std::uint32_t bad = b.addRobotTarget(crossing);
  const std::uint32_t good = b.addRobotTarget(clear);
  const Target& t = b.target(bad);
  EXPECT_EQ(t.status(), "too_close") << t.message;
  ASSERT_FALSE(t.clearances.empty());
  const auto& urethra = t.clearances.front();
  EXPECT_EQ(urethra.structure, "urethra");
  EXPECT_EQ(urethra.part, "stylet");
  EXPECT_LT(urethra.distance_mm, 0.0);  // it enters
  EXPECT_NE(t.message.find("'urethra'"), std::string::npos) << t.message;
  EXPECT_EQ(b.target(good).status(), "planned") << b.target(good).message;
  // The clearance against the closed form, where it does not enter: a target short of the
  // urethra, its stylet passing 1-2 mm from it. The mask draws the cylinder to half a voxel.
  const auto near = jointsTowards(0.55 * r_max - 3.0 - 2.2, z);
  const std::uint32_t close = b.addRobotTarget(near);
  const auto& c = b.target(close).clearances.front();
  const double half_voxel =
      0.5 * b.s.ct.volume->geometry.spacing_mm.norm();  // the voxel's half diagonal
  EXPECT_NEAR(c.distance_mm, urethraClearance(b.target(close).commandedJoints()), half_voxel);
  EXPECT_GT(c.uncertainty_mm, 0.0);
  EXPECT_EQ(b.target(close).status(), "too_close");  // within the 3 mm margin

  // lock_plan names each target too close; overrides need a reason and a target too close.
  const Reply locked = b.send(b.command(InputKind::kLockPlan));
  EXPECT_EQ(locked.error_code, "too_close");
  EXPECT_NE(locked.message.find(fmt::format("target {}", bad)), std::string::npos);
  const std::uint64_t revision = b.s.revision;
  EXPECT_EQ(b.send(withText(b, InputKind::kOverrideClearance, "  ", {bad})).error_code,
            "no_reason");
  EXPECT_EQ(b.send(withText(b, InputKind::kOverrideClearance, "why", {good})).error_code,
            "not_too_close");
  EXPECT_EQ(b.send(withText(b, InputKind::kOverrideClearance, "why", {99})).error_code,
            "unknown_target");
  EXPECT_EQ(b.s.revision, revision);  // refusals change nothing
  ASSERT_TRUE(b.send(withText(b, InputKind::kRemoveTarget, "", {close})).accepted);
  ASSERT_TRUE(b.send(withText(b, InputKind::kRemoveTarget, "", {good})).accepted);
  const std::string reason = "urethra stented; path agreed with the urologist";
  ASSERT_TRUE(b.send(withText(b, InputKind::kOverrideClearance, reason, {bad})).accepted);
  EXPECT_EQ(b.target(bad).status(), "planned");
  const Reply locked_now = b.send(b.command(InputKind::kLockPlan));
  ASSERT_TRUE(locked_now.accepted) << locked_now.message;
  EXPECT_NE(b.s.pending->summary.find("CLEARANCE OVERRIDDEN"), std::string::npos);
  EXPECT_NE(b.s.pending->summary.find(reason), std::string::npos) << b.s.pending->summary;
  EXPECT_NE(b.s.pending->summary.find("urethra"), std::string::npos);
}

TEST(Structures, RolesChangeByCommandAndBadTextChangesNothing) {
  Bench b;
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  const auto& kin = paperRobot()->kinematics;
  const double z = kin.tipDepthAtHome_mm(0.8 * kin.instrument().stylet_travel_mm) - 15.0;
  const std::uint32_t id = b.addRobotTarget(jointsTowards(0.85 * kin.maxRadius_mm(), z));
  ASSERT_EQ(b.target(id).status(), "too_close");
  const std::uint64_t revision = b.s.revision;
  for (const auto& [text, code] :
       std::vector<std::pair<std::string, std::string>>{{"urethra", "bad_role"},
                                                        {"urethra avoid", "bad_role"},
                                                        {"urethra avoid 12", "bad_role"},
                                                        {"urethra avoid nan", "bad_role"},
                                                        {"urethra dodge 3", "bad_role"},
                                                        {"urethra shown 2", "bad_role"},
                                                        {"kidney avoid 3", "unknown_structure"}}) {
    EXPECT_EQ(b.send(withText(b, InputKind::kStructureRole, text)).error_code, code) << text;
  }
  EXPECT_EQ(b.s.revision, revision);
  ASSERT_TRUE(b.send(withText(b, InputKind::kStructureRole, "Urethra shown")).accepted);
  EXPECT_EQ(b.target(id).status(), "planned");
  EXPECT_TRUE(b.target(id).clearances.size() == 2u);  // rectum and pubic arch
  ASSERT_TRUE(b.send(withText(b, InputKind::kStructureRole, "urethra avoid 1.5")).accepted);
  EXPECT_EQ(b.target(id).status(), "too_close");
}

TEST(Structures, AStructureLoadThatFailsLeavesTheSessionAsItWas) {
  Bench b;
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  const auto before = b.s.structures.loaded.set;
  // A file that is no segmentation, and one that does not exist (the server refuses a missing
  // file before the reducer; the job says so too).
  ASSERT_TRUE(loadStructures(b, IGNAV_SOURCE_DIR "/configs/server.yaml").accepted);
  EXPECT_EQ(b.s.structures.status, "loaded");
  EXPECT_EQ(b.s.structures.loaded.set, before);
  EXPECT_NE(b.s.structures.message.find("was refused"), std::string::npos)
      << b.s.structures.message;
  // A segmentation of another CT (the same anatomy on a grid of other voxels): refused by name,
  // the phantom's structures stay.
  volume::Geometry other = b.s.ct.volume->geometry;
  other.spacing_mm *= 1.25;
  const auto rp = registration::makeRobotPhantom(paperRobot()->kinematics,
                                                 paperRobot()->config.registration.scan);
  const auto drawn = anatomy::voxelise(other, rp->image_to_robot_true,
                                       phantomAnatomy(paperRobot()->kinematics), "other");
  ASSERT_TRUE(drawn.ok()) << drawn.error().message;
  const std::string file = (std::filesystem::temp_directory_path() /
                            ("ignav_other_ct_" + std::to_string(::getpid()) + ".seg.nrrd"))
                               .string();
  ASSERT_TRUE(anatomy::writeSegNrrd(*drawn, other, file).ok());
  const std::uint64_t revision = b.s.revision;
  ASSERT_TRUE(loadStructures(b, file).accepted);
  std::filesystem::remove(file);
  EXPECT_EQ(b.s.structures.loaded.set, before);
  EXPECT_NE(b.s.structures.message.find("was not made on this CT"), std::string::npos)
      << b.s.structures.message;
  EXPECT_EQ(b.s.revision, revision + 2);  // the command and its outcome, nothing else
  // A new CT drops the structures drawn on the old one.
  ASSERT_TRUE(b.send(withText(b, InputKind::kLoadVolume, kPhantomSource)).accepted);
  EXPECT_EQ(b.s.structures.status, "none");
  EXPECT_FALSE(b.s.structures.loaded.set);
}

// The phantom's anatomy exported as an RT Structure Set (as the server writes it beside the
// phantom) and loaded through the job: the same voxels. A structure set with a contour that
// crosses itself (written by pydicom) is refused by name, the structures before kept.
TEST(Structures, AnRtStructureSetDrawsTheSameVoxelsAndACrossedContourIsRefused) {
  Bench b;
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  const auto phantom = b.s.structures.loaded.set;
  ASSERT_TRUE(phantom);
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("ignav_rtstruct_" + std::to_string(::getpid())))
          .string();
  std::filesystem::create_directories(dir);
  const anatomy::CtFrame ct{b.s.ct.volume->geometry, b.s.ct.volume->frame_of_reference_uid,
                            "bench CT"};
  ASSERT_TRUE(anatomy::writeRtStructureSet(*phantom, ct, {}, dir + "/anatomy.dcm").ok());
  ASSERT_TRUE(loadStructures(b, dir + "/anatomy.dcm").accepted);
  ASSERT_EQ(b.s.structures.status, "loaded") << b.s.structures.message;
  const auto& read = *b.s.structures.loaded.set;
  ASSERT_EQ(read.structures.size(), phantom->structures.size());
  for (std::size_t n = 0; n < read.structures.size(); ++n) {
    const auto& a = read.structures[n];
    const auto& want = phantom->structures[n];
    SCOPED_TRACE(want.name);
    EXPECT_EQ(a.name, want.name);
    EXPECT_EQ(a.role, want.role);  // PTV / AVOIDANCE / ORGAN in the file
    EXPECT_EQ(a.mask.geometry.dims, want.mask.geometry.dims);
    EXPECT_LT((a.mask.geometry.origin_lps_mm - want.mask.geometry.origin_lps_mm).norm(), 1e-9);
    EXPECT_TRUE(a.mask.inside == want.mask.inside);
  }
  EXPECT_EQ(b.s.structures.loaded.fields.size(), read.structures.size());

  // A bow tie among the star's contours, on this CT's slices.
  const auto& g = b.s.ct.volume->geometry;
  ASSERT_TRUE(g.direction.isIdentity(1e-12));  // the script draws on axial grids
  const std::string grid =
      fmt::format(R"({{"origin": [{}, {}, {}], "spacing": [{}, {}, {}], "dims": [{}, {}, {}]}})",
                  g.origin_lps_mm.x(), g.origin_lps_mm.y(), g.origin_lps_mm.z(), g.spacing_mm.x(),
                  g.spacing_mm.y(), g.spacing_mm.z(), g.dims[0], g.dims[1], g.dims[2]);
  const std::string crossed = dir + "/crossed.dcm";
  ASSERT_EQ(std::system(("/usr/bin/python3 " IGNAV_SOURCE_DIR
                         "/tests/anatomy/rtstruct_reference.py make-crossing " +
                         crossed + " 1.2.3 '" + grid + "'")
                            .c_str()),
            0);
  const auto before = b.s.structures.loaded.set;
  const std::uint64_t revision = b.s.revision;
  ASSERT_TRUE(loadStructures(b, crossed).accepted);
  EXPECT_EQ(b.s.structures.loaded.set, before);
  const std::string& said = b.s.structures.message;
  EXPECT_NE(said.find("structure 'star': contour "), std::string::npos) << said;
  EXPECT_NE(said.find("crosses itself at (-20.30, -18.90, "), std::string::npos) << said;
  EXPECT_EQ(b.s.revision, revision + 2);
  std::filesystem::remove_all(dir);
}

Reply proposeTargets(Bench& b, const std::string& text) {
  return sendAndRunJob(b, InputKind::kProposeTargets, text, JobKind::kTargetProposal);
}

// The needle's surface from the rectum (a cylinder of 8 mm radius along the robot's axis at
// y = -(r_max + 12), phantom_anatomy.cpp) along the whole centreline, in closed form.
double rectumClearance(const kinematics::Joints& j) {
  const auto& kin = paperRobot()->kinematics;
  const auto line = kin.centreline(j, 0.01);
  const Eigen::Vector2d axis(0.0, -(kin.maxRadius_mm() + 12.0));
  const auto& in = kin.instrument();
  double best = 1e9;
  for (const auto& p : line.cannula_mm)
    best = std::min(best, (p.head<2>() - axis).norm() - 8.0 - 0.5 * in.cannula_outer_diameter_mm);
  for (const auto& p : line.stylet_mm)
    best = std::min(best, (p.head<2>() - axis).norm() - 8.0 - 0.5 * in.stylet_outer_diameter_mm);
  return best;
}

// Targets that fill the phantom's prostate from one insertion, checked against closed forms:
// each inside the prostate, on one lattice of the spacing, its needle clear of the urethra and
// the rectum by their margins; and every lattice point inside that the needle reaches with room
// to spare (2 mm beyond the margins: more than the uncertainty) is among them. Accepted, they
// lock as one insertion within 360°.
TEST(Proposals, TargetsFillTheProstateFromOneInsertionClearOfTheUrethraAndRectum) {
  Bench b;
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  const auto& kin = paperRobot()->kinematics;
  const auto& reg = *b.s.registration;
  const double spacing = 8.0;
  ASSERT_TRUE(proposeTargets(b, "Prostate 8").accepted);  // names ignore case
  ASSERT_EQ(b.s.proposals.status, "proposed") << b.s.proposals.message;
  const auto proposed = b.s.proposals.targets;
  ASSERT_GE(proposed.size(), 10u);
  ASSERT_LE(proposed.size(), 100u);
  EXPECT_NE(b.s.proposals.message.find("too close to 'urethra'"), std::string::npos)
      << b.s.proposals.message;
  const auto shapes = phantomAnatomy(kin);
  const auto& prostate_sdf = shapes[0].sdf;
  const double half_voxel = 0.5 * b.s.ct.volume->geometry.spacing_mm.norm();
  const Eigen::Vector3d origin = reg.toRobot(proposed.front().lps_mm);
  std::set<std::array<long, 3>> cells;  // lattice indices from the first
  for (const auto& p : proposed) {
    const Eigen::Vector3d r = reg.toRobot(p.lps_mm);
    EXPECT_LE(prostate_sdf(r), half_voxel) << r.transpose();
    const Eigen::Vector3d cell = (r - origin) / spacing;
    EXPECT_LT((cell - cell.array().round().matrix()).norm(), 1e-6) << "off the lattice";
    cells.insert({std::lround(cell.x()), std::lround(cell.y()), std::lround(cell.z())});
    const auto solution = kin.inverse(r).value();
    ASSERT_TRUE(solution.reachable());
    EXPECT_GE(urethraClearance(solution.joints), 3.0) << r.transpose();
    EXPECT_GE(rectumClearance(solution.joints), 5.0) << r.transpose();
  }
  EXPECT_EQ(cells.size(), proposed.size());  // no point twice
  // Every lattice point inside the prostate that the needle reaches with room to spare.
  std::size_t expected = 0;
  for (int c = -30; c <= 30; ++c)
    for (int bb = -20; bb <= 20; ++bb)
      for (int a = -20; a <= 20; ++a) {
        const Eigen::Vector3d r = origin + spacing * Eigen::Vector3d(a, bb, c);
        if (prostate_sdf(r) > -half_voxel) continue;
        const auto solution = kin.inverse(r);
        if (!solution || !solution->reachable()) continue;
        if (urethraClearance(solution->joints) < 5.0 || rectumClearance(solution->joints) < 7.0) {
          continue;
        }
        ++expected;
        EXPECT_TRUE(cells.count({a, bb, c}) == 1) << "missing " << r.transpose();
      }
  EXPECT_GT(expected, 0u);

  // Accepted two by id, then the rest: targets, planned, locked as one insertion.
  ASSERT_TRUE(b.send(b.command(InputKind::kAcceptProposals, {}, {proposed[1].id, proposed[0].id}))
                  .accepted);
  EXPECT_EQ(b.s.targets.size(), 2u);
  EXPECT_EQ(b.s.proposals.targets.size(), proposed.size() - 2);
  EXPECT_EQ(b.send(b.command(InputKind::kAcceptProposals, {}, {proposed[0].id})).error_code,
            "unknown_proposal");
  ASSERT_TRUE(b.send(b.command(InputKind::kAcceptProposals)).accepted);
  EXPECT_EQ(b.s.targets.size(), proposed.size());
  EXPECT_TRUE(b.s.proposals.targets.empty());
  for (const auto& t : b.s.targets)
    EXPECT_EQ(t.status(), "planned") << t.message;
  EXPECT_EQ(b.send(b.command(InputKind::kAcceptProposals)).error_code, "no_proposals");
  const Reply locked = b.send(b.command(InputKind::kLockPlan));
  ASSERT_TRUE(locked.accepted) << locked.message;
}

TEST(Proposals, BadRequestsAreRefusedAndTooManyTargetsNamesACoarserSpacing) {
  Bench b;
  EXPECT_EQ(b.send(withText(b, InputKind::kProposeTargets, "prostate 5")).error_code,
            "no_structures");
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  const std::uint64_t revision = b.s.revision;
  EXPECT_EQ(b.send(withText(b, InputKind::kProposeTargets, "prostate")).error_code, "bad_spacing");
  EXPECT_EQ(b.send(withText(b, InputKind::kProposeTargets, "prostate 0.5")).error_code,
            "bad_spacing");
  EXPECT_EQ(b.send(withText(b, InputKind::kProposeTargets, "prostate nan")).error_code,
            "bad_spacing");
  EXPECT_EQ(b.send(withText(b, InputKind::kProposeTargets, "bladder 5")).error_code,
            "unknown_structure");
  EXPECT_EQ(b.send(b.command(InputKind::kAcceptProposals)).error_code, "no_proposals");
  EXPECT_EQ(b.s.revision, revision);  // refusals change nothing
  // A fine lattice: more than one insertion takes; the message names a spacing that fits.
  ASSERT_TRUE(proposeTargets(b, "prostate 4").accepted);
  ASSERT_EQ(b.s.proposals.status, "failed");
  const std::string& said = b.s.proposals.message;
  const auto at = said.find("a spacing of ");
  ASSERT_NE(at, std::string::npos) << said;
  const double fits = std::stod(said.substr(at + 13));
  EXPECT_GT(fits, 4.0);
  ASSERT_TRUE(proposeTargets(b, fmt::format("prostate {:g}", fits)).accepted);
  EXPECT_EQ(b.s.proposals.status, "proposed") << b.s.proposals.message;
  EXPECT_LE(b.s.proposals.targets.size(), 100u);
  // It is the finest that fits: half a millimetre finer keeps too many.
  ASSERT_TRUE(proposeTargets(b, fmt::format("prostate {:g}", fits - 0.5)).accepted);
  EXPECT_EQ(b.s.proposals.status, "failed") << b.s.proposals.message;
  // New structures drop what was proposed in the old ones.
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  EXPECT_EQ(b.s.proposals.status, "none");
}

// ---- Where to mount the robot (place_robot) ----

// The outcome of every job of `kind` the session awaits, fed back.
void runJobs(Bench& b, JobKind kind) {
  for (const auto& job : pendingJobs(b.s))
    if (job.kind == kind) b.feed(job.run({}));
}

// The coverage model the job builds, made here from the session's own parts: what the job
// judges a point by, to compare with the session's verdict on a target there.
placement::CoverageModel sessionModel(const Session& s, double sample_mm) {
  placement::CoverageInputs in;
  in.kinematics = std::make_shared<const kinematics::Kinematics>(s.robot->kinematics);
  in.markers_robot_mm = s.robot->feature_points_mm;
  in.fle_mm = s.robot->config.registration.fle_mm;
  in.kind = s.robot->config.registration.kind;
  const auto& set = s.structures.loaded.set;
  in.target = std::shared_ptr<const anatomy::Structure>(set, set->find("prostate"));
  for (std::size_t n = 0; n < set->structures.size(); ++n)
    if (s.structures.roles[n].role == anatomy::Role::kAvoid)
      in.avoided.push_back({set->structures[n].name, s.structures.loaded.fields[n],
                            s.structures.roles[n].margin_mm});
  return placement::CoverageModel::create(in, sample_mm).value();
}

TEST(Placement, TheRobotIsPlacedThenTheMountedRobotIsMeasuredAgainstTheProposal) {
  Bench b;
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  // A wider margin for the pubic arch than the site's 2 mm: among the search's starts is then an
  // axis whose every needle passes too close (the web viewer's test showed it as an alternative
  // covering 0 %).
  ASSERT_TRUE(b.send(withText(b, InputKind::kStructureRole, "pubic_arch avoid 4")).accepted);
  const Reply started = b.send(withText(b, InputKind::kPlaceRobot, "prostate from superior"));
  ASSERT_TRUE(started.accepted) << started.message;
  EXPECT_EQ(b.s.robot_placement.status, "placing");
  runJobs(b, JobKind::kRobotPlacement);
  const auto& p = b.s.robot_placement;
  ASSERT_EQ(p.status, "placed") << p.message;
  ASSERT_GE(p.poses.size(), 2u);
  EXPECT_EQ(p.limits.approach, "superior");
  // Each alternative a choice: it covers some of the structure, never more than the proposal.
  for (std::size_t n = 1; n < p.poses.size(); ++n) {
    EXPECT_LE(p.poses[n].coverage.covered, p.poses[0].coverage.covered);
    EXPECT_GT(p.poses[n].coverage.covered, 0u) << "alternative " << n;
  }
  EXPECT_NE(p.message.find("one insertion covers"), std::string::npos) << p.message;

  // The outcome is journaled with its poses: replay takes them from the record.
  auto record = parseJournalRecord(b.journal.back());
  ASSERT_TRUE(record.ok()) << record.error().message;
  ASSERT_EQ(record->input.placements.size(), p.poses.size());
  EXPECT_TRUE(record->input.placements[0].pose.rotation.isApprox(p.poses[0].pose.rotation, 1e-12));
  EXPECT_EQ(record->input.placements[0].coverage.covered, p.poses[0].coverage.covered);

  // Registered already: the mounted robot (where the phantom put it) is measured at once.
  ASSERT_NE(p.checking, 0u);
  runJobs(b, JobKind::kPlacementCheck);
  ASSERT_TRUE(p.mounted.has_value()) << p.mounted_message;
  EXPECT_LT(p.mounted->coverage.covered * p.poses[0].coverage.samples,
            p.poses[0].coverage.covered * p.mounted->coverage.samples);
  EXPECT_GT(p.mounted->deviation.axis_deg, 1.0);
  EXPECT_NE(p.mounted_message.find("points less"), std::string::npos) << p.mounted_message;

  // The check's coverage counts points by the rules a target is judged by: targets placed at a
  // sample of its points are plannable exactly where the model says covered (a few may sit on a
  // margin's edge, where the needle's sampling decides).
  const auto model = sessionModel(b.s, 2.5);
  const auto pose = placement::RobotPose::of(*b.s.registration);
  std::size_t tried = 0, agree = 0, covered = 0;
  for (std::size_t n = 0; n < model.samples(); n += 23) {
    const Eigen::Vector3d point = model.samplePoints()[n];
    const Reply added = b.send(b.command(InputKind::kAddTarget, {point}));
    ASSERT_TRUE(added.accepted) << added.message;
    const bool plannable = b.target(added.target_id).plannable();
    const bool judged = model.judge(pose, point) == 0;
    ++tried;
    agree += plannable == judged ? 1 : 0;
    covered += judged ? 1 : 0;
    ASSERT_TRUE(b.send(b.command(InputKind::kRemoveTarget, {}, {added.target_id})).accepted);
  }
  EXPECT_GT(tried, 150u);
  EXPECT_GT(covered, tried / 3);
  EXPECT_GE(agree, tried - tried / 50) << agree << " of " << tried;

  // A registration anew measures again.
  auto fiducials = registration::makeRobotPhantom(paperRobot()->kinematics,
                                                  paperRobot()->config.registration.scan)
                       .value()
                       .spec.fiducials_lps_mm;
  for (auto& f : fiducials)
    f += Eigen::Vector3d(3.0, 0.0, 0.0);  // the robot mounted 3 mm to the left
  ASSERT_TRUE(b.send(b.command(InputKind::kSetFiducials, fiducials)).accepted);
  EXPECT_FALSE(p.mounted.has_value());
  ASSERT_NE(p.checking, 0u);
  runJobs(b, JobKind::kPlacementCheck);
  ASSERT_TRUE(p.mounted.has_value());
  EXPECT_GT(p.mounted->deviation.entry_mm, 1.0);

  // A new set of structures drops the placement.
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  EXPECT_EQ(b.s.robot_placement.status, "none");
}

TEST(Placement, BadRequestsAreRefusedAndChangeNothing) {
  Bench b;
  EXPECT_EQ(b.send(withText(b, InputKind::kPlaceRobot, "prostate")).error_code, "no_structures");
  ASSERT_TRUE(loadStructures(b, kPhantomSource).accepted);
  EXPECT_EQ(b.send(withText(b, InputKind::kPlaceRobot, "bladder")).error_code, "unknown_structure");
  const Reply bad_side = b.send(withText(b, InputKind::kPlaceRobot, "prostate from above"));
  EXPECT_EQ(bad_side.error_code, "bad_approach");
  EXPECT_NE(bad_side.message.find("'above'"), std::string::npos);
  EXPECT_EQ(b.s.robot_placement.status, "none");
  ASSERT_TRUE(b.send(withText(b, InputKind::kPlaceRobot, "prostate from superior")).accepted);
  const auto placing = b.s.robot_placement.placing;
  EXPECT_EQ(b.send(withText(b, InputKind::kPlaceRobot, "prostate")).error_code, "busy");
  EXPECT_EQ(b.s.robot_placement.placing, placing);
  // An outcome of another placement (not the one awaited) is refused as stale.
  Input stale = Bench::internal(InputKind::kRobotPlaced);
  stale.job = placing + 1000;
  stale.path = "prostate from superior";
  b.feed(stale);
  EXPECT_EQ(b.s.robot_placement.status, "placing");
}
}  // namespace
}  // namespace ignav::workflow
