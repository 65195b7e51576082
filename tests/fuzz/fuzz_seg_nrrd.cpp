// 3D Slicer segmentations (.seg.nrrd: layers, Segment<N>_* fields) on a mutated file: read, and
// when read, every structure's mask holds what its box declares and is not empty.
#include "fuzz_support.hpp"
#include "ignav/anatomy/structures.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ignav::fuzz::scratchFile(data, size, ".seg.nrrd");
  auto set = ignav::anatomy::readSegNrrd(path);
  if (!set.ok()) return 0;
  for (const auto& s : set->structures) {
    if (s.mask.inside.size() != s.mask.geometry.voxelCount() || s.mask.count() == 0)
      __builtin_trap();
  }
  return 0;
}
