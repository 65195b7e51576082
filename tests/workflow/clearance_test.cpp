// The patient's structures in the reducer (issue 41), without DDS: the built-in phantom's anatomy
// loaded through its job, a target whose needle crosses the urethra refused by name with the
// closest approach the closed form gives, lock_plan refusing it, an operator's override with a
// reason in the approval request, roles changed by command, and bad input leaving the session
// as it was.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include <fmt/format.h>

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

// load_structures, then its job run here as the server's job thread would, its outcome fed back.
Reply loadStructures(Bench& b, const std::string& source) {
  const Reply started = b.send(withText(b, InputKind::kLoadStructures, source));
  if (!started.accepted) return started;
  for (const auto& job : pendingJobs(b.s)) {
    if (job.kind == JobKind::kStructureLoad) b.feed(job.run({}));
  }
  return started;
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

}  // namespace
}  // namespace ignav::workflow
