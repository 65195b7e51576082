// Scratch folders for tests that write files: one per test under a per-process root, which is
// removed when the test program ends (ctest runs tests of one binary in parallel processes).
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace ignav::volume::testing {

namespace fs = std::filesystem;
using Bytes = std::vector<std::uint8_t>;

inline fs::path scratchRoot() {
  return fs::temp_directory_path() / ("ignav_tests_" + std::to_string(::getpid()));
}

class ScratchCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(scratchRoot(), ec);
  }
};
inline ::testing::Environment* const kScratchCleanup =
    ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

// An empty folder named after the running test.
inline fs::path scratchDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  fs::path dir = scratchRoot() / (std::string(info->test_suite_name()) + "." + info->name());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Writes header text followed by binary data; returns the path as a string.
inline std::string writeFile(const fs::path& path, const std::string& header,
                             const Bytes& data = {}) {
  std::ofstream out(path, std::ios::binary);
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
  return path.string();
}

}  // namespace ignav::volume::testing
