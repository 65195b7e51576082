// The MetaImage reader (.mha: header and attached data) on a mutated file.
#include "fuzz_support.hpp"
#include "ignav/volume/image_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ignav::fuzz::scratchFile(data, size, ".mha");
  auto v = ignav::volume::readMetaImage(path);
  if (v.ok() && v->voxels.size() != v->geometry.voxelCount()) __builtin_trap();
  return 0;
}
