// Volume files as 3D Slicer and ITK write them: NRRD (.nrrd, .nhdr + data file) and MetaImage
// (.mha, .mhd + raw). Every reader checks the header against the file before allocating, and
// every failure names the file and the problem.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "ignav/core/expected.hpp"
#include "ignav/volume/volume.hpp"

namespace ignav::volume {

// Voxel types: int8/uint8/int16 are stored exactly. Wider integer and floating types are
// stored exactly when their values lie on a grid of at most 65536 levels (value_scale /
// value_offset absorb the step and the shift); anything else is kUnsupported, never rounded.
Expected<Volume> readNrrd(const std::string& path, const ProgressCallback& progress = {});
Expected<Volume> readMetaImage(const std::string& path, const ProgressCallback& progress = {});

enum class NrrdEncoding { kRaw, kGzip };
// Attached .nrrd in LPS with space directions/origin, as Slicer reads it. int16 when every
// physical value is an integer in int16 range (value_scale 1, integral offset), else float.
Status writeNrrd(const Volume& volume, const std::string& path,
                 NrrdEncoding encoding = NrrdEncoding::kGzip);

// A NRRD of integer labels whose first axis may list layers (a Slicer .seg.nrrd keeps overlapping
// segments in layers so), with its key:=value pairs (Slicer's Segment0_Name, ...), for the
// segmentation readers (modules/anatomy). `values` holds `components` labels per voxel of
// `geometry`, the layer fastest, then i, j, k.
struct NrrdLayers {
  Geometry geometry;
  int components = 1;
  std::vector<std::int16_t> values;
  std::vector<std::pair<std::string, std::string>> key_values;  // in the header's order
};
Expected<NrrdLayers> readNrrdLayers(const std::string& path);
// Attached gzip NRRD of unsigned 8-bit labels (values 0-255), a list axis first when there is
// more than one layer, with the key:=value pairs (keys without ':' or line breaks).
Status writeNrrdLayers(const NrrdLayers& image, const std::string& path);

// Voxels of any of the readers' types as they lie in memory (host byte order, i fastest), kept
// exactly as they came: an attached raw NRRD in LPS, `geometry` validated first. For a scan
// received over the network (OpenIGTLink IMAGE), saved so that it is read back like any file.
enum class VoxelType { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat, kDouble };
Status writeNrrdVoxels(const Geometry& geometry, VoxelType type, const char* voxels,
                       std::size_t bytes, const std::string& path);

// By extension: .nrrd .nhdr -> readNrrd, .mha .mhd -> readMetaImage (case-insensitive).
// Anything else (a DICOM folder or .dcm) is kUnsupported for now.
Expected<Volume> readVolumeFile(const std::string& path, const ProgressCallback& progress = {});

// Internal, shared by the NRRD and MetaImage readers (not for callers).
namespace detail {
enum class ScalarType { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat, kDouble };
const char* toString(ScalarType type);
struct RasterSource {
  std::string data_path;       // file holding the voxels
  std::int64_t byte_skip = 0;  // header bytes before the data; -1: data ends the file (raw)
  ScalarType type = ScalarType::kInt16;
  bool big_endian = false;
  bool compressed = false;  // zlib or gzip stream
};
// Reads volume.geometry.voxelCount() values into volume.voxels (setting value_scale/offset).
// `what` names the file in messages. The geometry must already be validated.
Status readRaster(const RasterSource& source, const std::string& what,
                  const ProgressCallback& progress, Volume& volume);
}  // namespace detail

}  // namespace ignav::volume
