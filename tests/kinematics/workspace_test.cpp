#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "ignav/kinematics/workspace_map.hpp"
#include "test_instruments.hpp"

namespace ignav::kinematics {
namespace {

using testing::paperInstrument;
constexpr double kPi = 3.14159265358979323846;

TEST(Workspace, PaperVolumeIs51_53cm3) {
  const auto w = Kinematics::create(paperInstrument()).value().workspace();
  EXPECT_NEAR(w.volume_paper_cm3, 51.53, 0.005);        // eq (18) as printed
  EXPECT_NEAR(w.zone_diameter_paper_mm, 40.50, 0.005);  // eq (19), "up to 40 mm"
  EXPECT_NEAR(w.volume_exact_cm3, 88.07, 0.005);        // MODEL.md §5
}

TEST(Workspace, RigidIdealModelEqualsEq18Exactly) {
  // ϕ = 0 (no clearance), rigid cannula, no offset: eq (18) is the exact reachable volume.
  Instrument g = paperInstrument();
  g.stylet_outer_diameter_mm = g.cannula_inner_diameter_mm;
  g.cannula_deflected_radius_mm = std::numeric_limits<double>::infinity();
  g.exit_offset = ExitOffset::kNone;
  const auto k = Kinematics::create(g).value();
  const auto w = k.workspace();
  EXPECT_EQ(k.exitAngle_rad(), 0.0);
  EXPECT_EQ(w.r_min_mm, 0.0);
  EXPECT_NEAR(w.volume_exact_cm3, w.volume_paper_cm3, 1e-12 * w.volume_paper_cm3);
  EXPECT_NEAR(w.r_max_mm, 0.5 * w.zone_diameter_paper_mm, 1e-12);
}

TEST(Workspace, MonteCarloVolumeAgreesWithShellIntegration) {
  // Classify random points of the bounding cylinder with the inverse solver: the hit fraction
  // times the cylinder volume must match π·zc_max·(r_max² - r_min²) (MODEL.md §5: within 0.5 %).
  const auto k = Kinematics::create(paperInstrument()).value();
  const double r_max = k.maxRadius_mm();
  const double z_hi = k.forward({0, 0, 0}).tip_mm.z() + 0.1;
  const double z_lo = k.forward({0, 40, 40}).tip_mm.z() - 0.1;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-r_max, r_max), z(z_lo, z_hi);
  int inside_cylinder = 0, hits = 0;
  for (int i = 0; i < 400000; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), z(rng));
    if (std::hypot(p.x(), p.y()) > r_max) continue;
    ++inside_cylinder;
    hits += k.inverse(p)->reachable() ? 1 : 0;
  }
  const double cylinder_cm3 = kPi * r_max * r_max * (z_hi - z_lo) / 1000.0;
  const double mc = cylinder_cm3 * hits / inside_cylinder;
  EXPECT_NEAR(mc, k.workspace().volume_exact_cm3, 0.005 * k.workspace().volume_exact_cm3);
}

TEST(WorkspaceMap, GridSamplesTheExactVolume) {
  const auto k = Kinematics::create(paperInstrument()).value();
  const auto map = computeWorkspaceMap(k, 0.5).value();
  EXPECT_NEAR(map.sampledVolume_cm3(), k.workspace().volume_exact_cm3,
              0.01 * k.workspace().volume_exact_cm3);
  // Every listed point is reachable and every point carries the stylet that reaches it.
  for (size_t i = 0; i < map.points_mm.size(); i += 997) {
    const Eigen::Vector3d p = map.points_mm[i].cast<double>();
    const auto s = k.inverse(p).value();
    EXPECT_TRUE(s.reachable()) << k.describe(s, p);
    EXPECT_NEAR(s.joints.z_s_mm, map.z_s_mm[i], 1e-3);
  }
}

TEST(WorkspaceMap, RejectsAnUnreasonableGrid) {
  const auto k = Kinematics::create(paperInstrument()).value();
  const auto bad = computeWorkspaceMap(k, 0.0);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("grid_mm"), std::string::npos);
  EXPECT_FALSE(computeWorkspaceMap(k, NAN).ok());
}

TEST(WorkspaceMap, PlyHasAHeaderAnyViewerReadsAndOneRecordPerPoint) {
  const auto k = Kinematics::create(paperInstrument()).value();
  const auto map = computeWorkspaceMap(k, 2.0).value();
  const auto path = std::filesystem::temp_directory_path() / "ignav_workspace_test.ply";
  ASSERT_TRUE(writeWorkspacePly(map, path.string()).ok());
  std::ifstream in(path, std::ios::binary);
  std::string line, header;
  size_t vertices = 0;
  while (std::getline(in, line)) {
    header += line + "\n";
    std::sscanf(line.c_str(), "element vertex %zu", &vertices);
    if (line == "end_header") break;
  }
  EXPECT_EQ(header.rfind("ply\nformat binary_little_endian 1.0", 0), 0u) << header;
  EXPECT_EQ(vertices, map.points_mm.size());
  EXPECT_NE(header.find("property float intensity"), std::string::npos);
  // The first vertex record: x, y, z, intensity as little-endian float32.
  float record[4];
  in.read(reinterpret_cast<char*>(record), sizeof record);
  ASSERT_TRUE(in.good());
  EXPECT_EQ(record[0], map.points_mm[0].x());
  EXPECT_EQ(record[1], map.points_mm[0].y());
  EXPECT_EQ(record[2], map.points_mm[0].z());
  EXPECT_EQ(record[3], map.z_s_mm[0]);
  EXPECT_GE(std::filesystem::file_size(path) - header.size(), vertices * sizeof record);
  std::filesystem::remove(path);
  EXPECT_FALSE(writeWorkspacePly(map, "/nonexistent-dir/x.ply").ok());
}

}  // namespace
}  // namespace ignav::kinematics
