// The patient's structures (issue 41): segmentations of the session's CT, each a binary mask on
// the CT's own voxel grid with a name, a colour and a role. Read from 3D Slicer's .seg.nrrd
// (binary labelmap layers) or from a NRRD/MetaImage label map with a Slicer colour table naming
// its labels. Values only.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::anatomy {

// What the plan does with a structure: aims into it (target), keeps the needle a margin away
// from it (avoid), or only shows it (shown).
enum class Role { kTarget, kAvoid, kShown };
const char* toString(Role role);  // "target" | "avoid" | "shown"
std::optional<Role> roleNamed(std::string_view name);

// Structure names are told apart ignoring case ("Urethra" is "urethra"), as Slicer's users type
// them.
bool namesMatch(std::string_view a, std::string_view b);

// Voxel (i, j, k)'s place in a buffer of `dims` voxels, i fastest.
inline std::size_t gridIndex(const std::array<int, 3>& dims, int i, int j, int k) {
  return static_cast<std::size_t>(i) +
         static_cast<std::size_t>(dims[0]) *
             (static_cast<std::size_t>(j) +
              static_cast<std::size_t>(dims[1]) * static_cast<std::size_t>(k));
}

// A binary mask on a box of voxels: `geometry` is the box (its origin the first voxel's centre),
// `inside` holds 1 for the structure's voxels, i fastest.
struct Mask {
  volume::Geometry geometry;
  std::vector<std::uint8_t> inside;

  std::size_t index(int i, int j, int k) const { return gridIndex(geometry.dims, i, j, k); }
  std::size_t count() const;  // voxels inside
  double volume_cm3() const;
  // Is the voxel nearest this continuous (i, j, k) of the box inside? False beyond the box.
  bool insideNearest(const Eigen::Vector3d& ijk) const;
  // The box's corners (LPS): of the voxels' centres, widened by `margin_voxels` along each axis
  // (0.5: the voxels' cubes).
  std::array<Eigen::Vector3d, 8> corners(double margin_voxels = 0.0) const;
};

struct Structure {
  std::string name;
  std::array<double, 3> colour_rgb{0.5, 0.5, 0.5};  // 0-1, as Slicer writes Segment0_Color
  Mask mask;                                        // cropped to the structure's voxels
  Role role = Role::kShown;
  double margin_mm = 0.0;  // avoid: how close the needle's surface may come
};

struct StructureSet {
  std::string source;  // the file read
  std::vector<Structure> structures;
  // What the file held that did not become a structure, or was not checked, for people (e.g.
  // "'Isocenter 1' holds points only: not a volume").
  std::vector<std::string> notes;
  // By name, ignoring case; nullptr when none is so named.
  const Structure* find(std::string_view name) const;
  Structure* find(std::string_view name);
};

// The box of `grid` holding every voxel that is set, as a mask on that box; an error naming
// `what` when none is set.
Expected<Mask> cropMask(const volume::Geometry& grid, const std::vector<std::uint8_t>& inside,
                        const std::string& what);

// A 3D Slicer segmentation (.seg.nrrd): 3D, or 4D with a first axis of layers (overlapping
// segments); each segment's name, colour, label value and layer from its Segment<N>_* fields.
// Empty segments, labels out of range, missing names are refused, naming the segment.
Expected<StructureSet> readSegNrrd(const std::string& path);
// Writes every structure as one segment on `grid` (each mask's voxels must lie on it), a layer
// per structure where they overlap, as Slicer reads it.
Status writeSegNrrd(const StructureSet& set, const volume::Geometry& grid, const std::string& path);

// A label map (.nrrd/.nhdr/.mha/.mhd: 0 background, each other value a structure) named by a
// 3D Slicer colour table (lines "LABEL NAME R G B A", 0-255 colours, '#' comments): every label
// present must be named there.
Expected<StructureSet> readLabelMap(const std::string& path, const std::string& colour_table);

// The CT structures are read for: DICOM structures are drawn on its grid and must share its
// frame of reference.
struct CtFrame {
  volume::Geometry geometry;
  std::string frame_of_reference_uid;  // "" when the CT's files carry none (NRRD, MetaImage)
  std::string name;                    // for messages: the CT's source
};

// By name: *.seg.nrrd -> readSegNrrd; another .nrrd/.nhdr/.mha/.mhd -> readLabelMap with the
// colour table beside it (<stem>.ctbl or <stem>.txt); anything else is read as DICOM (an RT
// Structure Set or a Segmentation, dicom_structures.hpp) onto `ct`.
Expected<StructureSet> readStructures(const std::string& path, const CtFrame& ct);

// A set made on this CT: every mask's axes and spacing the CT's, its voxels on the CT's voxel
// centres (within 1 % of a voxel) and inside the CT. Otherwise an error saying which structure
// and how it differs (reason "other_ct").
Status checkOnCt(const StructureSet& set, const volume::Geometry& ct, const std::string& ct_name);

// A structure given by a signed distance (mm, negative inside) in a frame of its own: the
// built-in phantom's anatomy (in the robot's frame), tests' closed forms.
struct Shape {
  std::string name;
  std::array<double, 3> colour_rgb{0.5, 0.5, 0.5};
  Role role = Role::kShown;
  double margin_mm = 0.0;
  std::function<double(const Eigen::Vector3d&)> sdf;
};
// Each shape drawn on `grid` (the voxels whose centre lies inside it), `lps_to_shape` taking a
// voxel's LPS centre to the shapes' frame. A shape that covers no voxel is an error naming it.
Expected<StructureSet> voxelise(const volume::Geometry& grid, const Eigen::Matrix4d& lps_to_shape,
                                const std::vector<Shape>& shapes, const std::string& source);

}  // namespace ignav::anatomy
