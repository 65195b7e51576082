#include "scene.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "ignav/dosimetry/isodose.hpp"
#include "ignav/kinematics/reachable_region.hpp"
#include "ignav/surfaces/surfaces.hpp"

namespace ignav::server {

using protocol::SceneReply;
using protocol::SceneRequest;
using protocol::SceneSurface;

namespace {

SceneSurface surfaceOf(surfaces::TriangleMesh mesh, std::string name, std::string kind,
                       const std::array<double, 3>& colour_rgb) {
  SceneSurface s;
  s.name = std::move(name);
  s.kind = std::move(kind);
  s.colour_rgb = colour_rgb;
  s.points_lps = std::move(mesh.points_lps);
  s.triangles = std::move(mesh.triangles);
  return s;
}

std::array<double, 3> unitColour(const volume::Rgb& c) {
  return {c.r / 255.0, c.g / 255.0, c.b / 255.0};
}

// How long a surface took, for the log: made once per change, it is the scene's slow part.
struct Timed {
  const char* what;
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  std::size_t made = 0;
  ~Timed() {
    spdlog::info("scene: {} ({} surfaces) made in {:.0f} ms", what, made,
                 std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                     .count());
  }
};

}  // namespace

SceneBuilder::Averaged SceneBuilder::averagedOf(const volume::Volume& ct, std::uint32_t max) {
  // Blocks of f voxels along each axis averaged into one, f the least that brings the axis to at
  // most `max`; a last partial block is left out (under f voxels at the far face).
  const auto& g = ct.geometry;
  Averaged a;
  a.max_per_axis = max;
  std::array<int, 3> f{};
  for (int axis = 0; axis < 3; ++axis) {
    f[axis] = (g.dims[axis] + static_cast<int>(max) - 1) / static_cast<int>(max);
    a.dims[axis] = static_cast<std::uint32_t>(std::max(1, g.dims[axis] / f[axis]));
  }
  // The block's centre: (f - 1) / 2 voxels in from its first voxel.
  Eigen::Matrix4d block = Eigen::Matrix4d::Identity();
  for (int axis = 0; axis < 3; ++axis) {
    block(axis, axis) = f[axis];
    block(axis, 3) = (f[axis] - 1) / 2.0;
  }
  a.ijk_to_lps = g.ijkToLps() * block;
  if (f[0] * f[1] * f[2] == 1) return a;  // small enough: the CT's own voxels are served
  a.voxels.resize(static_cast<std::size_t>(a.dims[0]) * a.dims[1] * a.dims[2]);
  const double per_block = static_cast<double>(f[0]) * f[1] * f[2];
  std::size_t n = 0;
  for (std::uint32_t k = 0; k < a.dims[2]; ++k) {
    for (std::uint32_t j = 0; j < a.dims[1]; ++j) {
      for (std::uint32_t i = 0; i < a.dims[0]; ++i) {
        double sum = 0.0;
        for (int dk = 0; dk < f[2]; ++dk)
          for (int dj = 0; dj < f[1]; ++dj)
            for (int di = 0; di < f[0]; ++di)
              sum += ct.voxels[ct.index(static_cast<int>(i) * f[0] + di,
                                        static_cast<int>(j) * f[1] + dj,
                                        static_cast<int>(k) * f[2] + dk)];
        a.voxels[n++] = static_cast<std::int16_t>(std::lround(sum / per_block));
      }
    }
  }
  return a;
}

SceneReply SceneBuilder::build(const SceneRequest& request, const workflow::Session& session) {
  SceneReply out;
  out.client_id = request.client_id;
  out.request_id = request.request_id;
  out.part = request.part;
  if (!session.ct.volume) {
    out.message = "no CT is loaded";
    return out;
  }
  out.volume_id = fmt::format("{}#{}", session.ct.source, session.ct_revision);
  if (request.part == "volume") {
    volumePart(request, session, out);
  } else if (request.part == "surfaces") {
    surfacesPart(session, out);
  } else {
    out.message = "part '" + request.part + "' is not volume or surfaces";
  }
  return out;
}

void SceneBuilder::volumePart(const SceneRequest& request, const workflow::Session& session,
                              SceneReply& out) {
  const std::uint32_t max =
      request.max_voxels_per_axis == 0 ? kDefaultVoxelsPerAxis : request.max_voxels_per_axis;
  if (max < kMinVoxelsPerAxis || max > kMaxVoxelsPerAxis) {
    out.message = fmt::format("max_voxels_per_axis {} is outside {}..{}", max, kMinVoxelsPerAxis,
                              kMaxVoxelsPerAxis);
    return;
  }
  const auto& ct = session.ct.volume;
  if (averaged_of_ != ct || averaged_.max_per_axis != max) {
    averaged_ = averagedOf(*ct, max);
    averaged_of_ = ct;
  }
  const auto& a = averaged_;
  if (request.first_slice >= a.dims[2]) {
    out.message = fmt::format("first_slice {} is beyond the volume's {} slices",
                              request.first_slice, a.dims[2]);
    return;
  }
  const std::size_t slice_voxels = static_cast<std::size_t>(a.dims[0]) * a.dims[1];
  const auto per_slab = static_cast<std::uint32_t>(
      std::max<std::size_t>(1, kMaxSlabBytes / (slice_voxels * sizeof(std::int16_t))));
  out.slice_count = std::min(per_slab, a.dims[2] - request.first_slice);
  out.first_slice = request.first_slice;
  out.dims = a.dims;
  out.ijk_to_lps = protocol::toRowMajor(a.ijk_to_lps);
  out.value_scale = ct->value_scale;
  out.value_offset = ct->value_offset;
  // No voxels of its own: the CT needed no averaging and is served as it is.
  const std::int16_t* voxels = a.voxels.empty() ? ct->voxels.data() : a.voxels.data();
  const std::int16_t* first = voxels + slice_voxels * request.first_slice;
  out.voxels.assign(first, first + slice_voxels * out.slice_count);
  out.ok = true;
}

void SceneBuilder::surfacesPart(const workflow::Session& session, SceneReply& out) {
  out.surfaces = surfaces(session);
  out.ok = true;
}

std::vector<SceneSurface> SceneBuilder::surfaces(const workflow::Session& session) {
  std::vector<SceneSurface> out;
  for (const auto* part :
       {&structureSurfaces(session), &feasibleSurface(session), &isodoseSurfaces(session)}) {
    out.insert(out.end(), part->begin(), part->end());
  }
  return out;
}

const std::vector<SceneSurface>& SceneBuilder::structureSurfaces(const workflow::Session& s) {
  const auto& set = s.structures.loaded.set;
  if (set == structures_of_) return structures_;
  structures_.clear();
  structures_of_ = set;
  if (!set) return structures_;
  Timed timed{"structures"};
  for (const auto& structure : set->structures) {
    auto mesh = surfaces::maskSurface(structure.mask.geometry, structure.mask.inside,
                                      structure.name.c_str());
    if (!mesh) {
      spdlog::warn("scene: {}", mesh.error().message);
      continue;
    }
    structures_.push_back(
        surfaceOf(std::move(mesh).value(), structure.name, "structure", structure.colour_rgb));
  }
  timed.made = structures_.size();
  return structures_;
}

const std::vector<SceneSurface>& SceneBuilder::feasibleSurface(const workflow::Session& s) {
  const Eigen::Matrix4d registration =
      s.registration ? s.registration->imageToRobot() : Eigen::Matrix4d::Zero();
  if (s.robot == feasible_robot_ && registration == feasible_registration_) return feasible_;
  feasible_.clear();
  feasible_robot_ = s.robot;
  feasible_registration_ = registration;
  if (!s.robot || !s.registration) return feasible_;
  Timed timed{"feasible volume"};
  // The region sampled on a grid over its box in the robot's frame (at most ~2 M samples, no
  // coarser than needed for 1 mm: the region is smooth), its surface carried into the CT through
  // the registration.
  const kinematics::ReachableRegion region(s.robot->kinematics);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& corner : region.boundingBox()) {
    lo = lo.cwiseMin(corner);
    hi = hi.cwiseMax(corner);
  }
  const Eigen::Vector3d extent = hi - lo;
  const double step = std::max(1.0, std::cbrt(extent.prod() / 2.0e6));
  volume::Geometry grid;
  for (int axis = 0; axis < 3; ++axis)
    grid.dims[axis] = static_cast<int>(std::ceil(extent[axis] / step)) + 1;
  grid.spacing_mm = Eigen::Vector3d::Constant(step);
  grid.origin_lps_mm = lo;  // the robot's frame here, mapped below
  std::vector<std::uint8_t> inside(grid.voxelCount());
  std::size_t n = 0;
  for (int k = 0; k < grid.dims[2]; ++k)
    for (int j = 0; j < grid.dims[1]; ++j)
      for (int i = 0; i < grid.dims[0]; ++i)
        inside[n++] = region.contains(lo + step * Eigen::Vector3d(i, j, k)) ? 1 : 0;
  auto mesh = surfaces::maskSurface(grid, inside, "the feasible volume");
  if (!mesh) {
    spdlog::warn("scene: {}", mesh.error().message);
    return feasible_;
  }
  for (std::size_t v = 0; v < mesh->points_lps.size(); v += 3) {
    const Eigen::Vector3d robot(mesh->points_lps[v], mesh->points_lps[v + 1],
                                mesh->points_lps[v + 2]);
    const Eigen::Vector3d lps = s.registration->toImage(robot);
    for (int c = 0; c < 3; ++c)
      mesh->points_lps[v + static_cast<std::size_t>(c)] = static_cast<float>(lps[c]);
  }
  // A similarity keeps the winding unless it mirrors, which a registration never does.
  feasible_.push_back(surfaceOf(std::move(mesh).value(), "feasible volume", "feasible",
                                {0.0, 200 / 255.0, 80 / 255.0}));
  timed.made = 1;
  return feasible_;
}

const std::vector<SceneSurface>& SceneBuilder::isodoseSurfaces(const workflow::Session& s) {
  const auto* latest = s.dose.computed ? s.dose.computed->latest() : nullptr;
  const auto dose = latest ? latest->dose_Gy : nullptr;
  const double rx_Gy = s.dose.computed ? s.dose.computed->seeds.prescription_Gy : 0.0;
  if (dose == isodose_of_ && rx_Gy == isodose_rx_Gy_) return isodoses_;
  isodoses_.clear();
  isodose_of_ = dose;
  isodose_rx_Gy_ = rx_Gy;
  if (!dose) return isodoses_;
  Timed timed{"isodoses"};
  for (const auto& level : dosimetry::standardIsodoseLevels()) {
    const std::string name = fmt::format("isodose {:g}%", level.percent);
    auto mesh = surfaces::isoSurface(s.dose.computed->grid, *dose, rx_Gy * level.percent / 100.0,
                                     name.c_str());
    if (!mesh) {
      spdlog::warn("scene: {}", mesh.error().message);
      continue;
    }
    if (mesh->triangleCount() == 0) continue;  // no voxel reaches it
    isodoses_.push_back(
        surfaceOf(std::move(mesh).value(), name, "isodose", unitColour(level.colour)));
  }
  timed.made = isodoses_.size();
  return isodoses_;
}

}  // namespace ignav::server
