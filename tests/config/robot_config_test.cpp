#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "ignav/config/robot_config.hpp"
#include "ignav/config/tissue_profiles.hpp"

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

TEST(RobotConfig, RegistrationSectionIsOptionalWithDefaults) {
  std::string text = bundledText();
  const auto with = parseRobotConfig(text, "with.yaml");
  ASSERT_TRUE(with.ok()) << with.error().message;
  text.erase(text.find("  # Optional; every key"));
  const auto without = parseRobotConfig(text, "without.yaml");
  ASSERT_TRUE(without.ok()) << without.error().message;
  // The bundled file spells out the defaults, so both read the same.
  const auto& a = with->registration;
  const auto& b = without->registration;
  EXPECT_EQ(a.scan.scan_joints.z_s_mm, 40.0);
  EXPECT_EQ(b.scan.scan_joints.z_s_mm, 40.0);  // defaults to the stylet travel
  EXPECT_EQ(a.scan.cannula_base_mm, b.scan.cannula_base_mm);
  EXPECT_EQ(a.limits.max_fre_mm, b.limits.max_fre_mm);
  EXPECT_EQ(a.limits.min_spread_from_line_mm, b.limits.min_spread_from_line_mm);
  EXPECT_EQ(a.fle_mm, b.fle_mm);
  EXPECT_EQ(a.fiducials.min_hu, b.fiducials.min_hu);
  EXPECT_EQ(a.fiducials.max_volume_mm3, b.fiducials.max_volume_mm3);
  EXPECT_EQ(a.kind, registration::TransformKind::kSimilarity);
}

TEST(RobotConfig, ShorterCannulaWithoutRegistrationSectionLoads) {
  // Issue 23: a 90 mm cannula (z_fixed 50 + zs_max 40) without a `registration` section was
  // refused, "robot.registration.cannula_base_mm = 95 must lie on the straight part of the
  // cannula": the default must follow the geometry, the lower end of the straight part.
  std::string text = withValue("fixed_offset_mm", "50");
  text.erase(text.find("  # Optional; every key"));
  const auto config = parseRobotConfig(text, "short.yaml");
  ASSERT_TRUE(config.ok()) << config.error().message;
  EXPECT_EQ(config->registration.scan.cannula_base_mm, 50.0);
  const auto robot = makeRobot(*config, "short.yaml");
  ASSERT_TRUE(robot.ok()) << robot.error().message;
  // The base marker is on the axis, 50 mm below P0; the cannula tip 90 mm below it.
  EXPECT_EQ(robot->feature_points_mm[0], Eigen::Vector3d(0, 0, -50));
  EXPECT_NEAR(robot->feature_points_mm[1].z(), -90.0, 1e-12);
  // A longer curved section moves the straight part's end up: 50 + 40 - 45 = 45.
  std::string curved = withValue("curved_length_mm", "45");
  curved = std::regex_replace(curved, std::regex("fixed_offset_mm: 95"), "fixed_offset_mm: 50");
  curved.erase(curved.find("    cannula_base_mm"),
               curved.find("    transform:") - curved.find("    cannula_base_mm"));
  const auto partial = parseRobotConfig(curved, "partial.yaml");  // section present, key absent
  ASSERT_TRUE(partial.ok()) << partial.error().message;
  EXPECT_EQ(partial->registration.scan.cannula_base_mm, 45.0);
  EXPECT_TRUE(makeRobot(*partial, "partial.yaml").ok());
  // An explicit value past the straight part is still refused, naming the key and the range.
  EXPECT_NE(errorOf(withValue("fixed_offset_mm", "50")).find("cannula_base_mm = 95 must lie"),
            std::string::npos);
}

TEST(RobotConfig, RegistrationErrorsNameTheKey) {
  EXPECT_NE(errorOf(withValue("transform", "affine"))
                .find("robot.registration.transform: unknown value 'affine'"),
            std::string::npos);
  EXPECT_NE(errorOf(withValue("min_scale", "1.2")).find("robot.registration.min_scale: must be"),
            std::string::npos);
  EXPECT_NE(errorOf(withValue("fle_mm", "-1")).find("robot.registration.fle_mm: must be positive"),
            std::string::npos);
  EXPECT_NE(errorOf(withValue("cannula_base_mm", "120"))
                .find("robot.registration.cannula_base_mm = 120 must lie on the straight part"),
            std::string::npos)
      << errorOf(withValue("cannula_base_mm", "120"));
  EXPECT_NE(errorOf(withValue("scan_joints", "{theta_c_deg: 0, z_c_mm: 0, zs_mm: 40}"))
                .find("robot.registration.scan_joints.zs_mm: unknown key"),
            std::string::npos);
  const auto rigid = parseRobotConfig(withValue("transform", "rigid"), "x.yaml");
  ASSERT_TRUE(rigid.ok());
  EXPECT_EQ(rigid->registration.kind, registration::TransformKind::kRigid);
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

namespace ignav::config {
namespace {

TEST(TissueProfiles, BundledFileHoldsTableOneAndErrorsNameTheKey) {
  const auto profiles = loadTissueProfiles(IGNAV_SOURCE_DIR "/configs/tissues.yaml");
  ASSERT_TRUE(profiles.ok()) << profiles.error().message;
  const auto agar = tissueProfile(*profiles, "agar");
  ASSERT_TRUE(agar.ok());
  EXPECT_EQ(agar->tissue.lambda1, 0.49);  // seed 000, Table I
  EXPECT_EQ(agar->tissue.lambda2, 0.22);
  EXPECT_EQ(agar->needle.curvature_per_mm, -0.0025);
  EXPECT_EQ(tissueProfile(*profiles, "plastisol")->tissue.lambda1, 0.144);
  const auto missing = tissueProfile(*profiles, "liver");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("there are: agar, none, plastisol"), std::string::npos)
      << missing.error().message;

  const auto dir = std::filesystem::temp_directory_path() / "ignav_tissues_test";
  std::filesystem::create_directories(dir);
  auto load = [&](const std::string& text) {
    std::ofstream(dir / "t.yaml") << text;
    return loadTissueProfiles((dir / "t.yaml").string());
  };
  auto bad = load("tissues:\n  gel: {lambda1: 0.1, lambda_2: 0.2}\n");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("tissues.gel.lambda_2: unknown key"), std::string::npos)
      << bad.error().message;
  bad = load("tissues:\n  gel: {lambda1: 0, lambda2: 1}\n");  // inadmissible: (23)
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("tissues.gel: (23) fails"), std::string::npos)
      << bad.error().message;
  bad = load("needle: {wheelbase_mm: -1}\ntissues:\n  gel: {lambda1: 0, lambda2: 0}\n");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("needle.wheelbase_mm"), std::string::npos);
  // A tissue fitted with its curvature carries it; the others keep the needle's.
  const auto own = load(
      "needle: {curvature_per_mm: -0.0025, wheelbase_mm: 20}\ntissues:\n"
      "  fitted: {lambda1: 0.3, lambda2: 0.2, curvature_per_mm: -0.003}\n"
      "  plain: {lambda1: 0, lambda2: 0}\n");
  ASSERT_TRUE(own.ok()) << own.error().message;
  EXPECT_EQ(tissueProfile(*own, "fitted")->needle.curvature_per_mm, -0.003);
  EXPECT_EQ(tissueProfile(*own, "plain")->needle.curvature_per_mm, -0.0025);
  bad = load("tissues:\n  gel: {lambda1: 0, lambda2: 0, curvature_per_mm: .nan}\n");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("tissues.gel.curvature_per_mm: must be finite"),
            std::string::npos)
      << bad.error().message;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace ignav::config
