// The 3D view's scene through a real server over DDS (issue 43): the CT by slabs, exactly the
// voxels of the DICOM series the server wrote for its phantom (read here) and, averaged down, the
// means of their blocks computed here; the structures' surfaces on the boundary of the voxels of
// the segmentation the server wrote, enclosing their volume; the feasible volume's on the boundary
// of the robot's reachable region through the registration; after a seed plan is accepted, each
// isodose surface where the dose the server wrote (dose/planned_dose.nrrd, read here) is its level;
// bad requests refused by name with the server running on. Real ignav-server process over Cyclone
// DDS on loopback; domain 124.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <regex>

#include "ignav/anatomy/structures.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/kinematics/reachable_region.hpp"
#include "ignav/protocol/wire/messages.hpp"
#include "ignav/volume/dicom.hpp"
#include "server_process.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

constexpr std::uint32_t kDomain = 124;

// Every slab of the volume at `max` voxels a side, put together.
protocol::SceneReply wholeVolume(protocol::Client& c, std::uint32_t max) {
  protocol::SceneReply all;
  std::uint32_t next = 0;
  int slabs = 0;
  do {
    const auto slab = c.scene("volume", next, max, 60s);
    EXPECT_TRUE(slab.ok) << slab.message;
    if (!slab.ok) return all;
    if (slabs++ == 0) {
      all = slab;
      all.voxels.clear();
    }
    EXPECT_EQ(slab.first_slice, next);
    EXPECT_EQ(slab.volume_id, all.volume_id);
    EXPECT_EQ(slab.voxels.size(),
              static_cast<std::size_t>(slab.dims[0]) * slab.dims[1] * slab.slice_count);
    all.voxels.insert(all.voxels.end(), slab.voxels.begin(), slab.voxels.end());
    next += slab.slice_count;
  } while (next < all.dims[2]);
  all.slice_count = next;
  return all;
}

Eigen::Matrix4d matrixOf(const protocol::RowMajor4& m) {
  Eigen::Matrix4d out;
  for (int i = 0; i < 16; ++i)
    out(i / 4, i % 4) = m[static_cast<std::size_t>(i)];
  return out;
}

Eigen::Vector3d vertex(const protocol::SceneSurface& s, std::size_t i) {
  return {s.points_lps[3 * i], s.points_lps[3 * i + 1], s.points_lps[3 * i + 2]};
}

double enclosed_mm3(const protocol::SceneSurface& s) {
  double six = 0.0;
  for (std::size_t t = 0; t + 2 < s.triangles.size(); t += 3)
    six += vertex(s, s.triangles[t])
               .dot(vertex(s, s.triangles[t + 1]).cross(vertex(s, s.triangles[t + 2])));
  return six / 6.0;
}

// A raw float NRRD as the server writes the dose (dosimetry/dose_nrrd.hpp), read by its header's
// sizes, space directions and origin: its grid and values.
struct FloatNrrd {
  volume::Geometry grid;
  std::vector<float> values;
  double at(const Eigen::Vector3d& lps) const {
    const auto v = volume::trilinear(grid.dims, grid.toIjk(lps), [&](int i, int j, int k) {
      return values[static_cast<std::size_t>(i) +
                    static_cast<std::size_t>(grid.dims[0]) *
                        (static_cast<std::size_t>(j) + static_cast<std::size_t>(grid.dims[1]) * k)];
    });
    return v ? *v : NAN;
  }
};

FloatNrrd readFloatNrrd(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  FloatNrrd out;
  std::string line;
  const std::regex vector(R"(\(([^,]+),([^,]+),([^)]+)\))");
  while (std::getline(in, line) && !line.empty()) {
    if (line.rfind("sizes: ", 0) == 0) {
      std::istringstream sizes(line.substr(7));
      sizes >> out.grid.dims[0] >> out.grid.dims[1] >> out.grid.dims[2];
    }
    std::vector<Eigen::Vector3d> found;
    for (std::sregex_iterator m(line.begin(), line.end(), vector), end; m != end; ++m)
      found.emplace_back(std::stod((*m)[1]), std::stod((*m)[2]), std::stod((*m)[3]));
    if (line.rfind("space directions: ", 0) == 0 && found.size() == 3) {
      for (int a = 0; a < 3; ++a) {
        out.grid.spacing_mm[a] = found[static_cast<std::size_t>(a)].norm();
        out.grid.direction.col(a) = found[static_cast<std::size_t>(a)] / out.grid.spacing_mm[a];
      }
    }
    if (line.rfind("space origin: ", 0) == 0 && found.size() == 1)
      out.grid.origin_lps_mm = found[0];
  }
  out.values.resize(out.grid.voxelCount());
  in.read(reinterpret_cast<char*>(out.values.data()),
          static_cast<std::streamsize>(out.values.size() * sizeof(float)));
  if (!in) out.values.clear();
  return out;
}

TEST(SceneE2E, TheCtBySlabsTheStructuresAndTheFeasibleVolumeAsTheirFilesAndTheRobotSayIt) {
  ServerProcess server(kDomain);
  auto op = server.client("operator");

  // Before a CT: refused, and said why.
  const auto none = op->scene("volume", 0, 0, 30s);
  EXPECT_FALSE(none.ok);
  EXPECT_EQ(none.message, "no CT is loaded");

  registeredPhantom(*op);
  ASSERT_TRUE(op->send("load_structures", {"phantom:", {}, {}}).accepted);
  op->waitFor([](const json& s) { return stateText(s, "structures", "status") == "loaded"; }, 60s);
  const json state = op->state();

  // The CT at full resolution: the series' voxels exactly, its geometry as VolumeState says.
  auto series = volume::readDicomSeries({(server.sessionDir() / "phantom_ct").string()});
  ASSERT_TRUE(series.ok()) << series.error().message;
  const volume::Volume& ct = series->volume;
  const auto full = wholeVolume(*op, 1024);
  ASSERT_EQ(full.dims[0], static_cast<std::uint32_t>(ct.geometry.dims[0]));
  ASSERT_EQ(full.dims[1], static_cast<std::uint32_t>(ct.geometry.dims[1]));
  ASSERT_EQ(full.dims[2], static_cast<std::uint32_t>(ct.geometry.dims[2]));
  ASSERT_EQ(full.voxels.size(), ct.voxels.size());
  EXPECT_TRUE(std::equal(full.voxels.begin(), full.voxels.end(), ct.voxels.begin()));
  EXPECT_LT((matrixOf(full.ijk_to_lps) - ct.geometry.ijkToLps()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_EQ(full.value_scale, ct.value_scale);
  EXPECT_EQ(full.value_offset, ct.value_offset);
  for (int i = 0; i < 16; ++i)
    EXPECT_NEAR(full.ijk_to_lps[static_cast<std::size_t>(i)],
                state["volume"]["ijk_to_lps"][static_cast<std::size_t>(i)].get<double>(), 1e-9);

  // Averaged to at most 32 a side: each voxel the mean of its block, at the block's centre.
  const auto small = wholeVolume(*op, 32);
  std::array<int, 3> f{};
  for (int a = 0; a < 3; ++a) {
    f[a] = (ct.geometry.dims[a] + 31) / 32;
    EXPECT_EQ(small.dims[a], static_cast<std::uint32_t>(ct.geometry.dims[a] / f[a]))
        << "axis " << a;
    EXPECT_LE(small.dims[a], 32u);
  }
  ASSERT_EQ(small.voxels.size(),
            static_cast<std::size_t>(small.dims[0]) * small.dims[1] * small.dims[2]);
  int off = 0;
  std::size_t n = 0;
  for (std::uint32_t k = 0; k < small.dims[2]; ++k)
    for (std::uint32_t j = 0; j < small.dims[1]; ++j)
      for (std::uint32_t i = 0; i < small.dims[0]; ++i) {
        double sum = 0.0;
        for (int c = 0; c < f[2]; ++c)
          for (int b = 0; b < f[1]; ++b)
            for (int a = 0; a < f[0]; ++a)
              sum +=
                  ct.voxels[ct.index(static_cast<int>(i) * f[0] + a, static_cast<int>(j) * f[1] + b,
                                     static_cast<int>(k) * f[2] + c)];
        if (std::abs(small.voxels[n++] - sum / (f[0] * f[1] * f[2])) > 0.5) ++off;
      }
  EXPECT_EQ(off, 0) << "voxels not the mean of their block";
  const Eigen::Vector3d block_centre((f[0] - 1) / 2.0, (f[1] - 1) / 2.0, (f[2] - 1) / 2.0);
  EXPECT_LT((matrixOf(small.ijk_to_lps).col(3).head<3>() - ct.geometry.toLps(block_centre)).norm(),
            1e-9);
  EXPECT_LT((matrixOf(small.ijk_to_lps).col(0).head<3>() -
             f[0] * (ct.geometry.toLps({1, 0, 0}) - ct.geometry.toLps({0, 0, 0})))
                .norm(),
            1e-9);

  // The surfaces: four structures and the feasible volume.
  const auto scene = op->scene("surfaces", 0, 0, 60s);
  ASSERT_TRUE(scene.ok) << scene.message;
  auto segmentation =
      anatomy::readSegNrrd((server.sessionDir() / "phantom_anatomy.seg.nrrd").string());
  ASSERT_TRUE(segmentation.ok()) << segmentation.error().message;
  std::map<std::string, const protocol::SceneSurface*> by_name;
  for (const auto& s : scene.surfaces)
    by_name[s.kind + ":" + s.name] = &s;
  EXPECT_EQ(scene.surfaces.size(), 5u);
  for (const auto& s : scene.surfaces)
    std::cout << s.kind << " " << s.name << ": " << s.points_lps.size() / 3 << " vertices, "
              << s.triangles.size() / 3 << " triangles" << std::endl;
  for (const auto& structure : segmentation->structures) {
    SCOPED_TRACE(structure.name);
    const auto it = by_name.find("structure:" + structure.name);
    ASSERT_NE(it, by_name.end());
    const auto& surface = *it->second;
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(surface.colour_rgb[static_cast<std::size_t>(c)],
                  structure.colour_rgb[static_cast<std::size_t>(c)], 1e-6);
    // Every vertex on the boundary of the structure's voxels: among the voxels within 1.5 voxels
    // of it are some inside and some outside.
    const auto& mask = structure.mask;
    const Eigen::Matrix4d to_ijk = mask.geometry.lpsToIjk();
    const double mask_mm3 = static_cast<double>(mask.count()) * mask.geometry.spacing_mm.prod();
    int off_boundary = 0;
    const std::size_t vertices = surface.points_lps.size() / 3;
    for (std::size_t v = 0; v < vertices; ++v) {
      const Eigen::Vector3d ijk = (to_ijk * vertex(surface, v).homogeneous()).head<3>();
      bool in = false, out = false;
      for (int dk = -1; dk <= 2; ++dk)
        for (int dj = -1; dj <= 2; ++dj)
          for (int di = -1; di <= 2; ++di) {
            const Eigen::Vector3d voxel(std::floor(ijk.x()) + di, std::floor(ijk.y()) + dj,
                                        std::floor(ijk.z()) + dk);
            if ((voxel - ijk).norm() > 1.5) continue;
            (mask.insideNearest(voxel) ? in : out) = true;
          }
      if (!(in && out)) ++off_boundary;
    }
    EXPECT_EQ(off_boundary, 0) << "of " << vertices << " vertices";
    EXPECT_NEAR(enclosed_mm3(surface), mask_mm3, 0.15 * mask_mm3);
  }

  // The feasible volume: each vertex, carried back to the robot's frame, on the boundary of the
  // reachable region (some points within 1.5 mm reachable, some not).
  const auto it = by_name.find("feasible:feasible volume");
  ASSERT_NE(it, by_name.end());
  auto robot = config::loadRobot(state["robot"]["config_path"].get<std::string>());
  ASSERT_TRUE(robot.ok()) << robot.error().message;
  const kinematics::ReachableRegion region(robot->kinematics);
  Eigen::Matrix4d image_to_robot;
  for (int i = 0; i < 16; ++i)
    image_to_robot(i / 4, i % 4) =
        state["registration"]["image_to_robot"][static_cast<std::size_t>(i)].get<double>();
  const auto& feasible = *it->second;
  const std::size_t vertices = feasible.points_lps.size() / 3;
  ASSERT_GT(vertices, 100u);
  int off_boundary = 0;
  for (std::size_t v = 0; v < vertices; v += 7) {
    const Eigen::Vector3d p = (image_to_robot * vertex(feasible, v).homogeneous()).head<3>();
    bool in = false, out = false;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          (region.contains(p + 1.5 * Eigen::Vector3d(dx, dy, dz).normalized()) ? in : out) = true;
        }
    if (!(in && out)) ++off_boundary;
  }
  EXPECT_EQ(off_boundary, 0);
  const double feasible_cm3 = enclosed_mm3(feasible) / 1000.0;
  const double robot_cm3 = state["robot"]["feasible_volume_cm3"].get<double>();
  std::cout << "feasible volume: the surface encloses " << feasible_cm3 << " cm³, the robot says "
            << robot_cm3 << " cm³; " << vertices << " vertices" << std::endl;
  EXPECT_NEAR(feasible_cm3, robot_cm3, 0.05 * robot_cm3);

  // A seed plan accepted: its dose's isodose surfaces, each where the dose file says its level.
  ASSERT_TRUE(op->send("plan_seeds", {"prostate", {}, {}}).accepted);
  op->waitFor(
      [](const json& s) { return stateText(s, "structures", "proposal_status") == "proposed"; },
      60s);
  ASSERT_TRUE(op->send("accept_proposals").accepted);
  op->waitFor(
      [](const json& s) {
        const auto status = stateText(s, "structures", "dose_status");
        return status == "computed" || status == "failed";
      },
      120s);
  ASSERT_EQ(stateText(op->state(), "structures", "dose_status"), "computed");
  const std::string plan = stateText(op->state(), "structures", "proposal_message");
  const auto for_gy = plan.find(" Gy");
  ASSERT_NE(for_gy, std::string::npos) << plan;
  const double rx_Gy = std::stod(plan.substr(plan.rfind(' ', for_gy - 1) + 1));
  const FloatNrrd dose = readFloatNrrd(server.sessionDir() / "dose" / "planned_dose.nrrd");
  ASSERT_EQ(dose.values.size(), dose.grid.voxelCount());
  ASSERT_GT(dose.values.size(), 1000u);
  const auto with_dose = op->scene("surfaces", 0, 0, 60s);
  ASSERT_TRUE(with_dose.ok) << with_dose.message;
  int isodoses = 0;
  for (const auto& surface : with_dose.surfaces) {
    if (surface.kind != "isodose") continue;
    ++isodoses;
    SCOPED_TRACE(surface.name);
    const double level_Gy =
        rx_Gy * std::stod(surface.name.substr(surface.name.find(' ') + 1)) / 100.0;
    // Flying edges interpolates linearly along the grid's edges, where trilinear is linear too:
    // float's rounding only.
    const double tolerance_Gy = 1e-3 * level_Gy;
    int checked = 0, off_level = 0;
    for (std::size_t v = 0; v < surface.points_lps.size() / 3; v += 5) {
      const double at = dose.at(vertex(surface, v));
      if (std::isnan(at)) continue;  // where the grid's faces close it
      ++checked;
      if (std::abs(at - level_Gy) > tolerance_Gy) ++off_level;
    }
    std::cout << surface.name << ": " << checked << " vertices at " << level_Gy << " Gy, "
              << off_level << " off by more than " << tolerance_Gy << " Gy" << std::endl;
    EXPECT_GT(checked, 50);
    EXPECT_EQ(off_level, 0);
  }
  EXPECT_GE(isodoses, 3) << "50 %, 100 %, 150 % at least";

  // Bad requests: refused by name, the server answering on.
  const auto part = op->scene("mesh", 0, 0, 30s);
  EXPECT_FALSE(part.ok);
  EXPECT_EQ(part.message, "part 'mesh' is not volume or surfaces");
  const auto beyond = op->scene("volume", 100000, 0, 30s);
  EXPECT_FALSE(beyond.ok);
  EXPECT_NE(beyond.message.find("first_slice 100000 is beyond"), std::string::npos)
      << beyond.message;
  const auto tiny = op->scene("volume", 0, 8, 30s);
  EXPECT_FALSE(tiny.ok);
  EXPECT_NE(tiny.message.find("max_voxels_per_axis 8"), std::string::npos) << tiny.message;
  EXPECT_TRUE(op->send("query").accepted);
}

}  // namespace
}  // namespace ignav::e2e
