#include "ignav/surfaces/surfaces.hpp"

#include <fmt/format.h>
#include <vtkCellArray.h>
#include <vtkDiscreteFlyingEdges3D.h>
#include <vtkFloatArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataAlgorithm.h>
#include <vtkUnsignedCharArray.h>
#include <vtkWindowedSincPolyDataFilter.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>

namespace ignav::surfaces {

namespace {

// The padded grid: one voxel more on every side, so that what touches a face still closes.
std::array<int, 3> paddedDims(const volume::Geometry& grid) {
  return {grid.dims[0] + 2, grid.dims[1] + 2, grid.dims[2] + 2};
}

template <typename T, typename Array>
vtkNew<vtkImageData> paddedImage(const volume::Geometry& grid, const std::vector<T>& values,
                                 T outside) {
  const auto d = paddedDims(grid);
  vtkNew<vtkImageData> image;
  image->SetDimensions(d[0], d[1], d[2]);
  image->SetOrigin(-1.0, -1.0, -1.0);  // index space of `grid`: (0,0,0) is its first voxel
  image->SetSpacing(1.0, 1.0, 1.0);
  vtkNew<Array> scalars;
  scalars->SetNumberOfTuples(static_cast<vtkIdType>(d[0]) * d[1] * d[2]);
  T* out = scalars->GetPointer(0);
  std::fill(out, out + scalars->GetNumberOfTuples(), outside);
  const auto& g = grid.dims;
  for (int k = 0; k < g[2]; ++k) {
    for (int j = 0; j < g[1]; ++j) {
      const T* row =
          values.data() + static_cast<std::size_t>(g[0]) *
                              (static_cast<std::size_t>(j) + static_cast<std::size_t>(g[1]) * k);
      T* to = out + 1 +
              static_cast<std::size_t>(d[0]) *
                  (static_cast<std::size_t>(j + 1) + static_cast<std::size_t>(d[1]) * (k + 1));
      std::copy(row, row + g[0], to);
    }
  }
  image->GetPointData()->SetScalars(scalars);
  return image;
}

// Points from grid indices to LPS; triangles with their normals outwards (VTK's winding depends
// on the filter and on the direction's handedness, so it is checked by the enclosed volume).
TriangleMesh meshOf(vtkPolyData* poly, const volume::Geometry& grid) {
  TriangleMesh mesh;
  const Eigen::Matrix4d to_lps = grid.ijkToLps();
  const vtkIdType n = poly->GetNumberOfPoints();
  mesh.points_lps.reserve(static_cast<std::size_t>(n) * 3);
  std::vector<Eigen::Vector3d> lps(static_cast<std::size_t>(n));
  for (vtkIdType i = 0; i < n; ++i) {
    double p[3];
    poly->GetPoint(i, p);
    lps[static_cast<std::size_t>(i)] = (to_lps * Eigen::Vector4d(p[0], p[1], p[2], 1.0)).head<3>();
    for (int c = 0; c < 3; ++c)
      mesh.points_lps.push_back(static_cast<float>(lps[static_cast<std::size_t>(i)][c]));
  }
  vtkCellArray* polys = poly->GetPolys();
  mesh.triangles.reserve(static_cast<std::size_t>(polys->GetNumberOfCells()) * 3);
  vtkIdType count = 0;
  const vtkIdType* ids = nullptr;
  double signed_volume = 0.0;  // six times, by the divergence theorem
  for (polys->InitTraversal(); polys->GetNextCell(count, ids);) {
    if (count != 3) continue;  // flying edges makes triangles only
    for (int c = 0; c < 3; ++c)
      mesh.triangles.push_back(static_cast<std::uint32_t>(ids[c]));
    const auto& a = lps[static_cast<std::size_t>(ids[0])];
    signed_volume +=
        a.dot(lps[static_cast<std::size_t>(ids[1])].cross(lps[static_cast<std::size_t>(ids[2])]));
  }
  if (signed_volume < 0.0) {
    for (std::size_t t = 0; t + 2 < mesh.triangles.size(); t += 3)
      std::swap(mesh.triangles[t + 1], mesh.triangles[t + 2]);
  }
  return mesh;
}

Status checkSizes(const volume::Geometry& grid, std::size_t values, const char* what) {
  if (auto ok = grid.validate(what); !ok) return ok.error();
  if (values != grid.voxelCount()) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{}: {} values for a grid of {} x {} x {} voxels", what, values,
                                 grid.dims[0], grid.dims[1], grid.dims[2]));
  }
  return Ok{};
}

}  // namespace

Expected<TriangleMesh> maskSurface(const volume::Geometry& grid,
                                   const std::vector<std::uint8_t>& inside, const char* what,
                                   const SurfaceOptions& options) {
  if (auto ok = checkSizes(grid, inside.size(), what); !ok) return ok.error();
  std::vector<std::uint8_t> binary(inside.size());
  bool any = false;
  for (std::size_t i = 0; i < inside.size(); ++i) {
    binary[i] = inside[i] != 0 ? 1 : 0;
    any = any || binary[i] != 0;
  }
  if (!any) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{}: no voxel is set, so it has no surface", what));
  }
  auto image = paddedImage<std::uint8_t, vtkUnsignedCharArray>(grid, binary, 0);
  // The boundary between label 1 and its surroundings, where a mask's voxels end.
  vtkNew<vtkDiscreteFlyingEdges3D> edges;
  edges->SetInputData(image);
  edges->SetValue(0, 1.0);
  edges->ComputeNormalsOff();
  edges->ComputeGradientsOff();
  edges->ComputeScalarsOff();
  vtkNew<vtkWindowedSincPolyDataFilter> smooth;
  vtkPolyDataAlgorithm* last = edges;
  if (options.smoothing_iterations > 0) {
    smooth->SetInputConnection(edges->GetOutputPort());
    smooth->SetNumberOfIterations(options.smoothing_iterations);
    smooth->SetPassBand(options.pass_band);
    smooth->BoundarySmoothingOff();
    smooth->FeatureEdgeSmoothingOff();
    smooth->NonManifoldSmoothingOn();
    smooth->NormalizeCoordinatesOn();
    last = smooth;
  }
  last->Update();
  return meshOf(last->GetOutput(), grid);
}

Expected<TriangleMesh> isoSurface(const volume::Geometry& grid, const std::vector<float>& values,
                                  double level, const char* what) {
  if (auto ok = checkSizes(grid, values.size(), what); !ok) return ok.error();
  if (!std::isfinite(level)) {
    return makeError(ErrorCode::kInvalidArgument, fmt::format("{}: the level is not finite", what));
  }
  float lowest = static_cast<float>(level);
  for (float v : values) {
    if (!std::isfinite(v)) {
      return makeError(ErrorCode::kInvalidArgument, fmt::format("{}: a value is not finite", what));
    }
    lowest = std::min(lowest, v);
  }
  // Beyond the grid: lower than the level by as much as the field's lowest value is, so the
  // surface closes between the last voxel at or above it and the padding.
  const float outside = lowest - static_cast<float>(std::max(1.0, std::abs(level)));
  auto image = paddedImage<float, vtkFloatArray>(grid, values, outside);
  vtkNew<vtkFlyingEdges3D> edges;
  edges->SetInputData(image);
  edges->SetValue(0, level);
  edges->ComputeNormalsOff();
  edges->ComputeGradientsOff();
  edges->ComputeScalarsOff();
  edges->Update();
  return meshOf(edges->GetOutput(), grid);
}

}  // namespace ignav::surfaces
