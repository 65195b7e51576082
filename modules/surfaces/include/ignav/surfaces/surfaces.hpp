// Triangle meshes of what a 3D view shows (issue 43): the surface of a binary mask (a
// structure, the feasible volume voxelised) and isosurfaces of a scalar field (the dose), each in
// LPS millimetres, closed, its triangles wound with their normals outwards (towards lower values
// of a field: what it encloses is the mask, or the field at or above the level). Made once per
// change and sent as they are (the protocol's SceneSurface).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::surfaces {

struct TriangleMesh {
  std::vector<float> points_lps;         // x, y, z per vertex (mm)
  std::vector<std::uint32_t> triangles;  // three vertex indices per triangle

  std::size_t vertexCount() const { return points_lps.size() / 3; }
  std::size_t triangleCount() const { return triangles.size() / 3; }
};

struct SurfaceOptions {
  // Windowed-sinc smoothing passes (VTK's, which keeps the volume): 0 leaves the voxels' steps.
  int smoothing_iterations = 20;
  double pass_band = 0.1;  // lower: smoother
};

// The boundary of the voxels set in `inside` (one byte per voxel of `grid`, i fastest, nonzero
// inside): the 0.5 isosurface of the mask, padded so that voxels on the grid's faces close too,
// smoothed. An error naming `what` when no voxel is set or the sizes disagree.
Expected<TriangleMesh> maskSurface(const volume::Geometry& grid,
                                   const std::vector<std::uint8_t>& inside, const char* what,
                                   const SurfaceOptions& options = {});

// Where `values` (one per voxel of `grid`, i fastest) crosses `level`, interpolated linearly
// between voxel centres, not smoothed: the boundary of the field at or above the level (a dose's
// isodose surface), closed on the grid's faces as if the field were lower beyond them. Empty
// (no triangles) when nothing reaches the level.
Expected<TriangleMesh> isoSurface(const volume::Geometry& grid, const std::vector<float>& values,
                                  double level, const char* what);

}  // namespace ignav::surfaces
