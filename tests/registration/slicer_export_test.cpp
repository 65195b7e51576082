// Markups JSON checked field by field against Slicer's documented format (the markups
// developer guide); the .tfm is read back by ITK itself in itk_transform_test.cpp.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "ignav/registration/slicer_export.hpp"

namespace ignav::registration {
namespace {

TEST(SlicerExport, MarkupsJsonIsAnLpsFiducialList) {
  const std::vector<MarkupPoint> points{{"cannula_base", {-12.5, 3.25, 40.125}, "detected", true},
                                        {"T7", {1.0 / 3.0, -2e-7, 1e5}, "unreachable", false}};
  const std::string path = ::testing::TempDir() + "/ignav_points.mrk.json";
  ASSERT_TRUE(writeMarkupsJson("ignav fiducials", points, path).ok());
  std::ifstream in(path);
  const auto doc = nlohmann::json::parse(in);
  EXPECT_EQ(doc.at("@schema").get<std::string>().rfind("https://raw.githubusercontent.com/slicer/"
                                                       "slicer/master/Modules/Loadable/Markups/"
                                                       "Resources/Schema/markups-schema-v1.",
                                                       0),
            0u);
  ASSERT_EQ(doc.at("markups").size(), 1u);
  const auto& m = doc.at("markups")[0];
  EXPECT_EQ(m.at("type"), "Fiducial");
  EXPECT_EQ(m.at("coordinateSystem"), "LPS");
  EXPECT_EQ(m.at("name"), "ignav fiducials");
  ASSERT_EQ(m.at("controlPoints").size(), 2u);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& cp = m.at("controlPoints")[i];
    EXPECT_EQ(cp.at("label"), points[i].label);
    EXPECT_EQ(cp.at("positionStatus"), "defined");
    EXPECT_EQ(cp.at("locked").get<bool>(), points[i].locked);
    for (int a = 0; a < 3; ++a) {
      // Full precision: the text round-trips to the same double.
      EXPECT_EQ(cp.at("position")[a].get<double>(), points[i].position_lps_mm[a]);
    }
  }
}

TEST(SlicerExport, RefusesNonFinitePointsAndUnwritablePaths) {
  auto s = writeMarkupsJson("x", {{"bad", {0, std::nan(""), 0}, "", true}},
                            ::testing::TempDir() + "/bad.mrk.json");
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("'bad'"), std::string::npos);
  s = writeItkTransform(Registration{}, "/nonexistent-dir/x.tfm");
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kIo);
  EXPECT_NE(s.error().message.find("/nonexistent-dir/x.tfm"), std::string::npos);
}

}  // namespace
}  // namespace ignav::registration
