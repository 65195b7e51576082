// Robot placement (issue 41, part 4) against references outside its own search: the feasible
// volume's closed form (MODEL.md §5), a structure drawn at a known pose found again, a target the
// anatomy lets one insertion cover, the skin's entry on a slab in closed form, and — on the
// built-in phantom — a brute-force grid of poses it must come within 2 % of.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <Eigen/Geometry>

#include "ignav/anatomy/site.hpp"
#include "ignav/placement/robot_placement.hpp"
#include "support/phantom_ct.hpp"
#include "support/placement_scene.hpp"

namespace ignav::placement {
namespace {

using test::paperRobot;

volume::Geometry gridAround(const Eigen::Vector3d& centre, const Eigen::Vector3d& half,
                            double spacing_mm) {
  volume::Geometry g;
  g.spacing_mm = Eigen::Vector3d::Constant(spacing_mm);
  g.origin_lps_mm = centre - half;
  for (int a = 0; a < 3; ++a)
    g.dims[static_cast<std::size_t>(a)] =
        static_cast<int>(std::ceil(2.0 * half[a] / spacing_mm)) + 1;
  return g;
}

CoverageInputs inputsFor(const std::shared_ptr<const anatomy::StructureSet>& set) {
  return test::coverageInputs(set, *paperRobot());
}

std::shared_ptr<const anatomy::StructureSet> draw(const volume::Geometry& grid,
                                                  const Eigen::Matrix4d& lps_to_shape,
                                                  std::vector<anatomy::Shape> shapes) {
  auto set = anatomy::voxelise(grid, lps_to_shape, shapes, "test");
  EXPECT_TRUE(set.ok()) << (set.ok() ? "" : set.error().message);
  return std::make_shared<const anatomy::StructureSet>(std::move(set).value());
}

// The feasible volume itself, in the robot's frame, `inset_mm` inside its surfaces.
double feasibleSdf(const Eigen::Vector3d& q, double inset_mm) {
  const auto& kin = paperRobot()->kinematics;
  const double r = std::hypot(q.x(), q.y());
  if (r < kin.minRadius_mm() + inset_mm || r > kin.maxRadius_mm() - inset_mm) return 1.0;
  const double top = kin.tipDepthAtHome_mm(kin.styletForRadius_mm(r));
  const double travel = kin.instrument().cannula_travel_mm;
  return q.z() <= top - inset_mm && q.z() >= top - travel + inset_mm ? -1.0 : 1.0;
}

TEST(Coverage, ABoxAroundTheFeasibleVolumeIsCoveredAsMuchAsItsClosedFormVolume) {
  // MODEL.md §5: V = π·zc_max·(r_max² − r_min²) with r_min 1.803, r_max 26.535 mm: 88.07 cm³.
  const double v_closed_form_cm3 = M_PI * 40.0 * (26.535 * 26.535 - 1.803 * 1.803) / 1000.0;
  const auto grid = gridAround(Eigen::Vector3d(0, 0, -168), Eigen::Vector3d(29, 29, 40), 0.5);
  const auto set =
      draw(grid, Eigen::Matrix4d::Identity(),
           {{"box", {1, 0, 0}, anatomy::Role::kTarget, 0.0, [](const Eigen::Vector3d&) {
               return -1.0;
             }}});
  auto model = CoverageModel::create(inputsFor(set), 0.5);
  ASSERT_TRUE(model.ok());
  // Robot frame = LPS: the robot inserts along -Z, its +X along LPS +L.
  const auto pose = RobotPose::along(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -1));
  EXPECT_TRUE(pose.rotation.isApprox(Eigen::Matrix3d::Identity()));
  const auto c = model->coverage(pose);
  const double covered_cm3 = static_cast<double>(c.covered) * 0.125 / 1000.0;
  EXPECT_NEAR(covered_cm3, v_closed_form_cm3, 0.005 * v_closed_form_cm3);
  EXPECT_EQ(c.covered + c.unreachable, c.samples);
}

TEST(Search, AStructureDrawnAsTheFeasibleVolumeAtAKnownPoseIsFoundThere) {
  // The site's approach +S; the structure drawn at a pose tilted 8° from it, 4 mm aside.
  PlacementLimits limits;
  limits.insertion_lps = Eigen::Vector3d(0, 0, 1);
  const Eigen::Vector3d axis =
      Eigen::AngleAxisd(8.0 * M_PI / 180.0, Eigen::Vector3d(0.6, 0.8, 0)) * limits.insertion_lps;
  const auto truth = RobotPose::along(Eigen::Vector3d(4, -3, -170), axis);
  const Eigen::Vector3d centre = truth.toImage(Eigen::Vector3d(0, 0, -168));
  const auto grid = gridAround(centre, Eigen::Vector3d(40, 40, 45), 1.0);
  const auto set =
      draw(grid, truth.imageToRobot(),
           {{"ring", {1, 0, 0}, anatomy::Role::kTarget, 0.0, [](const Eigen::Vector3d& q) {
               return feasibleSdf(q, 0.75);
             }}});
  auto search = CoverageModel::create(inputsFor(set), 3.0);
  auto final = CoverageModel::create(inputsFor(set), 1.0);
  ASSERT_TRUE(search.ok() && final.ok());
  EXPECT_EQ(final->coverage(truth).covered, final->samples());  // the truth covers it all

  const auto placed = placeRobot(*search, *final, limits);
  ASSERT_TRUE(placed.ok()) << placed.error().message;
  const auto& best = placed->poses.front();
  EXPECT_GE(best.coverage.fraction(), 0.98);
  const double angle_deg =
      std::acos(std::clamp(best.pose.insertion().dot(truth.insertion()), -1.0, 1.0)) * 180 / M_PI;
  EXPECT_LT(angle_deg, 1.5);
  // The axes meet the structure's centre within a millimetre and a half; the origin's depth too.
  const Eigen::Vector3d d = centre - best.pose.origin_lps_mm;
  EXPECT_LT((d - d.dot(best.pose.insertion()) * best.pose.insertion()).norm(), 1.5);
  EXPECT_NEAR(d.dot(best.pose.insertion()), (centre - truth.origin_lps_mm).dot(truth.insertion()),
              1.5);
  EXPECT_NEAR(best.tilt_deg, 8.0, 1.5);
  // Alternatives are distinct poses, each covering less.
  for (std::size_t n = 1; n < placed->poses.size(); ++n)
    EXPECT_LE(placed->poses[n].coverage.covered, best.coverage.covered);
}

TEST(Search, OneInsertionCoversAtLeast95PercentWhenTheAnatomyAllowsIt) {
  // A 22 mm gland with a rectum 6 mm behind it (a 16 mm tube, margin 5 mm) and a pubic arch
  // above its front (an 8 mm bar, margin 2 mm): the needle may come from the perineum anywhere
  // within 20° and 20 mm.
  const auto grid = gridAround(Eigen::Vector3d::Zero(), Eigen::Vector3d(45, 45, 45), 1.0);
  auto tube = [](const Eigen::Vector3d& p, const Eigen::Vector3d& at, const Eigen::Vector3d& along,
                 double radius) {
    const Eigen::Vector3d d = p - at;
    return (d - d.dot(along) * along).norm() - radius;
  };
  const auto set =
      draw(grid, Eigen::Matrix4d::Identity(),
           {{"gland",
             {1, 0, 0},
             anatomy::Role::kTarget,
             0.0,
             [](const Eigen::Vector3d& p) { return p.norm() - 11.0; }},
            {"rectum",
             {0, 1, 0},
             anatomy::Role::kAvoid,
             5.0,
             [&](const Eigen::Vector3d& p) {
               return tube(p, Eigen::Vector3d(0, 25, 0), Eigen::Vector3d::UnitZ(), 8.0);
             }},
            {"pubic_arch", {0, 0, 1}, anatomy::Role::kAvoid, 2.0, [&](const Eigen::Vector3d& p) {
               return tube(p, Eigen::Vector3d(0, -20, 25), Eigen::Vector3d::UnitX(), 4.0);
             }}});
  auto search = CoverageModel::create(inputsFor(set), 2.0);
  auto final = CoverageModel::create(inputsFor(set), 1.0);
  ASSERT_TRUE(search.ok() && final.ok());
  PlacementLimits limits;  // inferior approach, 20°, 20 mm
  const auto placed = placeRobot(*search, *final, limits);
  ASSERT_TRUE(placed.ok()) << placed.error().message;
  const auto& best = placed->poses.front();
  EXPECT_GE(best.coverage.fraction(), 0.95);
  EXPECT_LE(best.tilt_deg, 20.0 + 1e-9);
  EXPECT_LE(best.shift_mm, 20.0 + 1e-9);
  // Straight up the middle the cannula itself would leave the gland's core out of reach (the
  // axis and a thin cylinder about it are not reachable): the search moved off it.
  const auto straight = RobotPose::along(Eigen::Vector3d(0, 0, -168), limits.insertion_lps);
  EXPECT_LT(final->coverage(straight).covered, best.coverage.covered);
}

TEST(Search, AStructureNoNeedleMayReachIsRefusedNotPlacedWithNothingCovered) {
  // A gland wrapped in a structure to avoid: every needle that reaches it passes through the
  // wrapping, so no pose covers any of it and there is no alternative to offer.
  const auto grid = gridAround(Eigen::Vector3d::Zero(), Eigen::Vector3d(25, 25, 25), 1.0);
  const auto set =
      draw(grid, Eigen::Matrix4d::Identity(),
           {{"gland",
             {1, 0, 0},
             anatomy::Role::kTarget,
             0.0,
             [](const Eigen::Vector3d& p) { return p.norm() - 8.0; }},
            {"capsule", {0, 1, 0}, anatomy::Role::kAvoid, 1.0, [](const Eigen::Vector3d& p) {
               return p.norm() - 20.0;
             }}});
  auto search = CoverageModel::create(inputsFor(set), 3.0);
  auto final = CoverageModel::create(inputsFor(set), 2.0);
  ASSERT_TRUE(search.ok() && final.ok());
  const auto placed = placeRobot(*search, *final, PlacementLimits{});
  ASSERT_FALSE(placed.ok()) << placed->poses.size() << " poses, the best covering "
                            << placed->poses.front().coverage.covered;
  EXPECT_EQ(placed.error().reason, "no_placement");
  EXPECT_NE(placed.error().message.find("covers any of the target with every clearance kept"),
            std::string::npos)
      << placed.error().message;
}

TEST(Skin, TheEntryIsWhereTheAxisCrossesTheSkinAndTheOriginStaysOutside) {
  // A CT of tissue (40 HU) below z = 0.5 mm (voxel centres every mm; z <= 0 tissue) and air
  // above: the -300 HU level lies 0.3 of a voxel above the last tissue centre (trilinear).
  auto ct = std::make_shared<volume::Volume>();
  ct->geometry = gridAround(Eigen::Vector3d(0, 0, -20), Eigen::Vector3d(30, 30, 40), 1.0);
  ct->voxels.resize(ct->geometry.voxelCount());
  for (int k = 0; k < ct->geometry.dims[2]; ++k)
    for (int j = 0; j < ct->geometry.dims[1]; ++j)
      for (int i = 0; i < ct->geometry.dims[0]; ++i)
        ct->voxels[ct->index(i, j, k)] =
            ct->geometry.toLps(Eigen::Vector3d(i, j, k)).z() <= 1e-9 ? 40 : -1000;
  const double skin_z = 0.3;  // 0 + (−300 − 40)/(−1000 − 40) of the way to z = 1
  const auto grid = gridAround(Eigen::Vector3d(0, 0, -30), Eigen::Vector3d(10, 10, 10), 1.0);
  const auto set =
      draw(grid, Eigen::Matrix4d::Identity(),
           {{"t", {1, 0, 0}, anatomy::Role::kTarget, 0.0, [](const Eigen::Vector3d& p) {
               return (p - Eigen::Vector3d(0, 0, -30)).norm() - 5.0;
             }}});
  auto in = inputsFor(set);
  in.ct = ct;
  auto model = CoverageModel::create(in, 2.0);
  ASSERT_TRUE(model.ok());
  const double tilt = 25.0 * M_PI / 180.0;
  const Eigen::Vector3d a(std::sin(tilt), 0, -std::cos(tilt));
  const auto pose = RobotPose::along(Eigen::Vector3d(0, 0, -30) - 150.0 * a, a);
  const auto skin = model->skinEntry(pose, -300.0);
  ASSERT_TRUE(skin.seen);
  const double t = (skin_z - pose.origin_lps_mm.z()) / a.z();  // along the axis to the plane
  EXPECT_NEAR(skin.skin_distance_mm, t, 0.05);
  EXPECT_NEAR(skin.entry_lps_mm.z(), skin_z, 0.05 * std::cos(tilt));

  // The search keeps the origin the site's distance outside the skin.
  PlacementLimits limits;
  limits.insertion_lps = Eigen::Vector3d(0, 0, -1);
  limits.min_skin_distance_mm = 120.0;  // deeper than the target allows: the origin stays out
  const auto placed = placeRobot(*model, *model, limits, 1);
  ASSERT_TRUE(placed.ok()) << placed.error().message;
  for (const auto& p : placed->poses) {
    EXPECT_GE(p.skin.skin_distance_mm, 120.0 - 1e-6);
    EXPECT_TRUE(p.skin.seen);
  }
  limits.min_skin_distance_mm = 300.0;  // nothing reaches the target from so far out
  const auto none = placeRobot(*model, *model, limits);
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.error().reason, "no_placement");
  EXPECT_NE(none.error().message.find("300 mm outside the skin"), std::string::npos);
}

TEST(Search, OnThePhantomTheSearchComesWithin2PercentOfABruteForceGrid) {
  auto scene =
      test::makePlacementScene(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml", 7.0, 7.0);
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  const auto placed = placeRobot(scene->search, scene->final, scene->limits);
  ASSERT_TRUE(placed.ok()) << placed.error().message;
  PoseGrid grid;
  grid.tilt_step_deg = 10.0;
  grid.shift_step_mm = 10.0;
  grid.depth_step_mm = 8.0;
  grid.threads = 2;
  std::size_t tried = 0;
  const auto brute = bruteForcePlacement(scene->search, scene->limits, grid, &tried);
  EXPECT_GT(tried, 2000u);
  const double found = placed->poses.front().coverage.fraction();
  EXPECT_GE(found, brute.coverage.fraction() - 0.02)
      << "search " << found << ", grid " << brute.coverage.fraction() << " of " << tried;
  // Where the phantom's robot was mounted covers less than the proposal (it was not placed for
  // this anatomy), and every pose stays within the site's limits and outside the skin.
  EXPECT_LT(scene->final.coverage(scene->mounted).fraction(), found);
  for (const auto& p : placed->poses) {
    EXPECT_LE(p.tilt_deg, scene->limits.max_tilt_deg + 1e-9);
    EXPECT_LE(p.shift_mm, scene->limits.max_shift_mm + 1e-9);
    EXPECT_GE(p.skin.skin_distance_mm, scene->limits.min_skin_distance_mm - 1e-6);
    EXPECT_TRUE(p.skin.seen);
  }
}

TEST(Limits, BadLimitsAndApproachesAreRefusedByName) {
  PlacementLimits limits;
  limits.max_tilt_deg = 50.0;
  auto bad = limits.validate();
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("max_tilt_deg"), std::string::npos);
  limits = {};
  limits.max_shift_mm = std::nan("");
  EXPECT_FALSE(limits.validate().ok());
  EXPECT_TRUE(anatomy::insertionFrom("Inferior")->isApprox(Eigen::Vector3d(0, 0, 1)));
  EXPECT_TRUE(anatomy::insertionFrom("anterior")->isApprox(Eigen::Vector3d(0, 1, 0)));
  EXPECT_FALSE(anatomy::insertionFrom("above").has_value());

  const auto dir = std::filesystem::temp_directory_path() / "ignav_placement_site_test";
  std::filesystem::create_directories(dir);
  const auto path = (dir / "site.yaml").string();
  std::ofstream(path) << "site: t\nstructures: []\nplacement: {approach: above}\n";
  auto site = anatomy::readSite(path);
  ASSERT_FALSE(site.ok());
  EXPECT_NE(site.error().message.find("placement.approach 'above'"), std::string::npos);
  std::ofstream(path) << "site: t\nstructures: []\nplacement: {approach: superior, "
                         "max_shift_mm: 80}\n";
  site = anatomy::readSite(path);
  ASSERT_FALSE(site.ok());
  EXPECT_NE(site.error().message.find("max_shift_mm"), std::string::npos);
  std::ofstream(path) << "site: t\nstructures: []\nplacement: {approach: superior, "
                         "max_tilt_deg: 10}\n";
  site = anatomy::readSite(path);
  ASSERT_TRUE(site.ok()) << site.error().message;
  EXPECT_TRUE(site->placement.insertion_lps.isApprox(Eigen::Vector3d(0, 0, -1)));
  EXPECT_EQ(site->placement.max_tilt_deg, 10.0);
  EXPECT_EQ(site->placement.max_shift_mm, 20.0);  // the default
  std::filesystem::remove_all(dir);

  // An empty target is refused when the model is made.
  CoverageInputs in;
  in.kinematics = std::make_shared<const kinematics::Kinematics>(paperRobot()->kinematics);
  EXPECT_FALSE(CoverageModel::create(in, 2.0).ok());
}

}  // namespace
}  // namespace ignav::placement
