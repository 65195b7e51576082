// The dose as NRRD (issue 42, part 5), read back by a third-party tool: plastimatch's `header`
// and `stats` (Debian's plastimatch, ITK's NRRD reader) give the grid and the values' minimum,
// mean and maximum, compared with the grid and the values written.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <regex>

#include "ignav/dosimetry/dose_nrrd.hpp"
#include "support/command_output.hpp"

namespace ignav::dosimetry {
namespace {

// The first number after `label` in `text`; NaN when absent.
double numberAfter(const std::string& text, const std::string& label) {
  const auto at = text.find(label);
  if (at == std::string::npos) return std::nan("");
  return std::strtod(text.c_str() + at + label.size(), nullptr);
}

TEST(DoseNrrd, PlastimatchReadsTheGridAndTheDoses) {
  volume::Geometry grid;
  grid.dims = {17, 13, 9};
  grid.spacing_mm = {1.5, 2.0, 2.5};
  grid.origin_lps_mm = {-12.25, 30.5, -101.0};
  std::vector<float> dose(grid.voxelCount());
  // An inverse-square dose around a point, so min, mean and max differ.
  const Eigen::Vector3d centre(0.0, 42.0, -90.0);
  for (int k = 0; k < 9; ++k)
    for (int j = 0; j < 13; ++j)
      for (int i = 0; i < 17; ++i) {
        const double r = (grid.toLps(Eigen::Vector3d(i, j, k)) - centre).norm();
        dose[static_cast<std::size_t>((k * 13 + j) * 17 + i)] =
            static_cast<float>(145.0 * 100.0 / std::max(r * r, 1.0));
      }
  const auto dir = std::filesystem::temp_directory_path() / "ignav_dose_nrrd_test";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "dose.nrrd").string();
  ASSERT_TRUE(writeDoseNrrd(dose, grid, path).ok());

  const std::string header = test::commandOutput("plastimatch header " + path + " 2>&1");
  SCOPED_TRACE(header);
  // plastimatch reports RAS-free ITK geometry: origin and spacing as written, LPS.
  const std::regex origin(R"(Origin\s*=\s*([-\d.e]+)\s+([-\d.e]+)\s+([-\d.e]+))");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(header, m, origin));
  EXPECT_NEAR(std::stod(m[1]), -12.25, 1e-4);
  EXPECT_NEAR(std::stod(m[2]), 30.5, 1e-4);
  EXPECT_NEAR(std::stod(m[3]), -101.0, 1e-4);
  const std::regex size(R"(Size\s*=\s*(\d+)\s+(\d+)\s+(\d+))");
  ASSERT_TRUE(std::regex_search(header, m, size));
  EXPECT_EQ(m[1], "17");
  EXPECT_EQ(m[2], "13");
  EXPECT_EQ(m[3], "9");
  const std::regex spacing(R"(Spacing\s*=\s*([-\d.e]+)\s+([-\d.e]+)\s+([-\d.e]+))");
  ASSERT_TRUE(std::regex_search(header, m, spacing));
  EXPECT_NEAR(std::stod(m[1]), 1.5, 1e-6);
  EXPECT_NEAR(std::stod(m[2]), 2.0, 1e-6);
  EXPECT_NEAR(std::stod(m[3]), 2.5, 1e-6);

  const std::string stats = test::commandOutput("plastimatch stats " + path + " 2>&1");
  SCOPED_TRACE(stats);
  const double sum = std::accumulate(dose.begin(), dose.end(), 0.0);
  EXPECT_NEAR(numberAfter(stats, "MIN"), *std::min_element(dose.begin(), dose.end()), 1e-3);
  EXPECT_NEAR(numberAfter(stats, "MAX"), *std::max_element(dose.begin(), dose.end()), 1e-3);
  EXPECT_NEAR(numberAfter(stats, "AVE"), sum / static_cast<double>(dose.size()), 1e-3);
  std::filesystem::remove_all(dir);
}

TEST(DoseNrrd, BadDosesAreRefusedNamingTheVoxel) {
  volume::Geometry grid;
  grid.dims = {2, 2, 2};
  std::vector<float> dose(8, 1.0f);
  dose[5] = -1.0f;
  const auto refused = writeDoseNrrd(dose, grid, "/tmp/never.nrrd");
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("voxel 5"), std::string::npos);
  EXPECT_FALSE(writeDoseNrrd(std::vector<float>(7, 1.0f), grid, "/tmp/never.nrrd").ok());
  EXPECT_EQ(
      writeDoseNrrd(std::vector<float>(8, 1.0f), grid, "/nonexistent/dir/d.nrrd").error().code,
      ErrorCode::kIo);
}

}  // namespace
}  // namespace ignav::dosimetry
