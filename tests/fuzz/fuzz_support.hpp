// Shared by the libFuzzer targets: a scratch file per process for the readers that take paths.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

namespace ignav::fuzz {

// Writes the input to one scratch file on tmpfs (rewritten every run) and returns its path.
inline std::string scratchFile(const std::uint8_t* data, std::size_t size, const char* suffix) {
  static const std::string path = "/dev/shm/ignav_fuzz_" + std::to_string(::getpid()) + suffix;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return path;
  if (size > 0) std::fwrite(data, 1, size, f);
  std::fclose(f);
  return path;
}

}  // namespace ignav::fuzz
