// The DICOM series reader on one mutated file (seeds: phantom slices, pydicom's test files).
// Anything may be refused; nothing may crash, hang or read out of bounds.
#include "fuzz_support.hpp"
#include "ignav/volume/dicom.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ignav::fuzz::scratchFile(data, size, ".dcm");
  auto result = ignav::volume::readDicomSeries({path});
  if (result.ok()) {
    // A volume that loads must be whole: as many voxels as its dimensions say.
    const auto& v = result->volume;
    if (v.voxels.size() != v.geometry.voxelCount()) __builtin_trap();
  }
  return 0;
}
