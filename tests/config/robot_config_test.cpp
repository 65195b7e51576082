#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>

#include "ignav/config/robot_config.hpp"

namespace ignav::config {
namespace {

std::string bundledText() {
  std::ifstream in(std::string(IGNAV_SOURCE_DIR) + "/configs/robots/torabi2014.yaml");
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The bundled config with one line's value replaced (or the line removed when value is empty).
std::string withValue(const std::string& key, const std::string& value) {
  std::string text = bundledText();
  const std::regex line("( *)" + key + ":[^\n]*\n");
  std::smatch m;
  EXPECT_TRUE(std::regex_search(text, m, line)) << key;
  const std::string replacement = value.empty() ? "" : m[1].str() + key + ": " + value + "\n";
  return std::regex_replace(text, line, replacement, std::regex_constants::format_first_only);
}

std::string errorOf(const std::string& yaml) {
  const auto c = parseRobotConfig(yaml, "test.yaml");
  if (!c) return c.error().message;
  const auto r = makeRobot(*c, "test.yaml");
  return r ? std::string() : r.error().message;
}

TEST(RobotConfig, BundledPaperInstrumentLoads) {
  const auto robot = loadRobot(std::string(IGNAV_SOURCE_DIR) + "/configs/robots/torabi2014.yaml");
  ASSERT_TRUE(robot.ok()) << robot.error().message;
  EXPECT_EQ(robot->config.name, "torabi2014");
  EXPECT_EQ(robot->config.instrument.stylet_radius_mm, 35.5);
  EXPECT_EQ(robot->config.instrument.cannula_deflected_radius_mm, 550.0);
  EXPECT_EQ(robot->config.instrument.exit_offset, kinematics::ExitOffset::kLateral);
  EXPECT_EQ(robot->config.transmission.coupling, actuation::Coupling::kCasing);
  EXPECT_EQ(robot->config.transmission.lead_mm, 1.5875);
}

TEST(RobotConfig, InfiniteDeflectedRadiusMeansARigidCannula) {
  const auto c = parseRobotConfig(withValue("deflected_radius_mm", ".inf"), "t");
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_TRUE(std::isinf(c->instrument.cannula_deflected_radius_mm));
  EXPECT_TRUE(makeRobot(*c, "t").ok());
}

TEST(RobotConfig, ErrorsNameTheFileAndKey) {
  EXPECT_EQ(
      errorOf(withValue("travel_mm", "")).rfind("test.yaml: robot.stylet.travel_mm: is missing", 0),
      0u)
      << errorOf(withValue("travel_mm", ""));
  EXPECT_NE(errorOf(withValue("radius_mm", "-3"))
                .find("robot.stylet.radius_mm: must be positive (got -3)"),
            std::string::npos);
  EXPECT_NE(errorOf(withValue("radius_mm", ".nan")).find("robot.stylet.radius_mm: is NaN"),
            std::string::npos);
  EXPECT_NE(errorOf(withValue("radius_mm", "abc"))
                .find("robot.stylet.radius_mm: expected a number, got 'abc'"),
            std::string::npos);
  EXPECT_NE(errorOf(withValue("outer_diameter_mm", "2.0")).find("wider than the cannula bore"),
            std::string::npos);
  EXPECT_NE(
      errorOf(withValue("exit_offset", "sideways"))
          .find(
              "robot.model.exit_offset: unknown value 'sideways'; expected axial | lateral | none"),
      std::string::npos);
  EXPECT_NE(
      errorOf(withValue("coupling", "belt")).find("robot.transmission.coupling: unknown value"),
      std::string::npos);
  EXPECT_NE(errorOf(withValue("microsteps", "0")).find("robot.transmission.microsteps"),
            std::string::npos);
  EXPECT_NE(
      errorOf(withValue("deflected_radius_mm", "20")).find("must exceed robot.stylet.radius_mm"),
      std::string::npos);
}

TEST(RobotConfig, MisspeltKeyIsRejectedNotIgnored) {
  std::string text = bundledText();
  text.replace(text.find("radius_mm: 35.5"), 9, "raduis_mm");
  EXPECT_NE(errorOf(text).find("robot.stylet.raduis_mm: unknown key"), std::string::npos)
      << errorOf(text);
  EXPECT_NE(errorOf(text + "extra: 1\n").find("extra: unknown key"), std::string::npos);
}

TEST(RobotConfig, UnreadableInput) {
  EXPECT_NE(errorOf("robot: [1, 2").find("not valid YAML"), std::string::npos);
  EXPECT_NE(errorOf("- a\n- b\n").find("robot: is missing"), std::string::npos);
  const auto missing = loadRobotConfig("/nonexistent/robot.yaml");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kIo);
  EXPECT_NE(missing.error().message.find("/nonexistent/robot.yaml"), std::string::npos);
}

}  // namespace
}  // namespace ignav::config
