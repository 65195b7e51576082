// What a shell command printed on its standard output, for tests that ask third-party tools
// (python3-pydicom, dicompyler-core, plastimatch) for their references; the command must succeed.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace ignav::test {

inline std::string commandOutput(const std::string& cmd) {
  std::string out;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (p == nullptr) return out;
  char buf[4096];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0)
    out.append(buf, n);
  EXPECT_EQ(::pclose(p), 0) << cmd;
  return out;
}

}  // namespace ignav::test
