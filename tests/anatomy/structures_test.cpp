// Segmentations in and out (issue 41): a .seg.nrrd written and read back voxel for voxel, a label
// map with a Slicer colour table, a site's roles, and every bad input refused by name.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "ignav/anatomy/site.hpp"
#include "ignav/anatomy/structures.hpp"
#include "ignav/volume/image_io.hpp"

namespace ignav::anatomy {
namespace {
namespace fs = std::filesystem;

class Structures : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("ignav_structures_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    ct_.dims = {40, 30, 20};
    ct_.spacing_mm = Eigen::Vector3d(0.8, 0.8, 1.5);
    ct_.origin_lps_mm = Eigen::Vector3d(-16, -12, -30);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // A structure of the voxels (on the CT) where `inside` holds.
  template <typename F>
  Structure structure(const std::string& name, F inside) const {
    std::vector<std::uint8_t> in(ct_.voxelCount(), 0);
    std::size_t n = 0;
    for (int k = 0; k < ct_.dims[2]; ++k)
      for (int j = 0; j < ct_.dims[1]; ++j)
        for (int i = 0; i < ct_.dims[0]; ++i, ++n)
          in[n] = inside(i, j, k) ? 1 : 0;
    Structure s;
    s.name = name;
    s.mask = cropMask(ct_, in, name).value();
    return s;
  }
  StructureSet anatomy() const {
    StructureSet set;
    set.structures.push_back(structure("prostate", [](int i, int j, int k) {
      return std::pow((i - 20) / 8.0, 2) + std::pow((j - 15) / 6.0, 2) +
                 std::pow((k - 10) / 5.0, 2) <=
             1.0;
    }));
    set.structures.push_back(structure("urethra", [](int i, int j, int) {
      return std::pow(i - 20, 2) + std::pow(j - 16, 2) <= 2;
    }));
    set.structures.push_back(structure("rectum", [](int i, int j, int k) {
      return j >= 23 && j <= 27 && i > 12 && i < 28 && k > 2;
    }));
    set.structures[0].colour_rgb = {0.9, 0.6, 0.2};
    set.structures[1].colour_rgb = {1.0, 1.0, 0.0};
    set.structures[1].role = Role::kAvoid;
    set.structures[1].margin_mm = 3.0;
    return set;
  }

  fs::path dir_;
  volume::Geometry ct_;
};

void expectSameMask(const Mask& a, const Mask& b) {
  EXPECT_EQ(a.geometry.dims, b.geometry.dims);
  EXPECT_LT((a.geometry.origin_lps_mm - b.geometry.origin_lps_mm).norm(), 1e-9);
  EXPECT_LT((a.geometry.spacing_mm - b.geometry.spacing_mm).norm(), 1e-9);
  EXPECT_TRUE(a.inside == b.inside);
}

TEST_F(Structures, ASegNrrdWithOverlappingSegmentsIsReadBackVoxelForVoxel) {
  const auto set = anatomy();  // the urethra runs through the prostate: two layers
  ASSERT_TRUE(writeSegNrrd(set, ct_, path("a.seg.nrrd")).ok());
  const auto layers = volume::readNrrdLayers(path("a.seg.nrrd"));
  ASSERT_TRUE(layers.ok());
  EXPECT_EQ(layers->components, 2);
  const auto back = readStructures(path("a.seg.nrrd"), {});
  ASSERT_TRUE(back.ok()) << back.error().message;
  ASSERT_EQ(back->structures.size(), 3u);
  for (std::size_t n = 0; n < 3; ++n) {
    const auto& a = set.structures[n];
    const auto& b = back->structures[n];
    EXPECT_EQ(a.name, b.name);
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(a.colour_rgb[static_cast<std::size_t>(c)],
                  b.colour_rgb[static_cast<std::size_t>(c)], 1e-6);
    EXPECT_EQ(a.role, b.role);
    EXPECT_EQ(a.margin_mm, b.margin_mm);
    expectSameMask(a.mask, b.mask);
  }
  EXPECT_TRUE(checkOnCt(*back, ct_, "ct").ok());
  EXPECT_NEAR(back->structures[0].mask.volume_cm3(),
              static_cast<double>(back->structures[0].mask.count()) * 0.8 * 0.8 * 1.5 / 1000.0,
              1e-12);
}

// Files as Slicer writes them by hand-made bytes (the fuzzer's seeds): labels in one layer,
// overlapping segments in two, and a file from before Slicer 4.11 (no LabelValue or Layer: one
// segment per layer, label 1).
TEST_F(Structures, SlicerFilesOfEachKindAreRead) {
  const std::string seeds = IGNAV_SOURCE_DIR "/tests/fuzz/seeds/seg_nrrd/";
  const auto one = readSegNrrd(seeds + "two_segments.seg.nrrd");
  ASSERT_TRUE(one.ok()) << one.error().message;
  ASSERT_EQ(one->structures.size(), 2u);
  EXPECT_EQ(one->structures[1].name, "urethra");
  EXPECT_EQ(one->structures[1].role, Role::kAvoid);
  EXPECT_EQ(one->structures[1].margin_mm, 3.0);
  EXPECT_EQ(one->structures[0].mask.count(), 2u);
  EXPECT_DOUBLE_EQ(one->structures[0].colour_rgb[1], 0.6);
  for (const char* file : {"two_layers.seg.nrrd", "old_slicer.seg.nrrd"}) {
    const auto two = readSegNrrd(seeds + file);
    ASSERT_TRUE(two.ok()) << two.error().message;
    ASSERT_EQ(two->structures.size(), 2u) << file;
    EXPECT_EQ(two->structures[0].mask.count(), 4u) << file;  // the gland holds the urethra
    EXPECT_EQ(two->structures[1].mask.count(), 2u) << file;
    // The urethra's first voxel (i 2, j 1) in LPS: origin + (2 x 0.8, 1 x 0.8, 0).
    EXPECT_LT(
        (two->structures[1].mask.geometry.origin_lps_mm - Eigen::Vector3d(0.1, 2.8, -30)).norm(),
        1e-9)
        << file;
  }
}

TEST_F(Structures, ALabelMapIsNamedByItsColourTable) {
  volume::Volume labels;
  labels.geometry = ct_;
  labels.voxels.assign(ct_.voxelCount(), 0);
  const auto set = anatomy();
  // Label 3 for the rectum, 7 for the urethra (no overlap kept: the urethra wins).
  for (const auto& [name, label] : {std::pair("rectum", 3), std::pair("urethra", 7)}) {
    const auto& m = set.find(name)->mask;
    for (int k = 0; k < m.geometry.dims[2]; ++k)
      for (int j = 0; j < m.geometry.dims[1]; ++j)
        for (int i = 0; i < m.geometry.dims[0]; ++i) {
          if (!m.inside[m.index(i, j, k)]) continue;
          const Eigen::Vector3d at = ct_.toIjk(m.geometry.toLps(Eigen::Vector3d(i, j, k)));
          labels.voxels[static_cast<std::size_t>(std::lround(at.x())) +
                        40u * (static_cast<std::size_t>(std::lround(at.y())) +
                               30u * static_cast<std::size_t>(std::lround(at.z())))] =
              static_cast<std::int16_t>(label);
        }
  }
  ASSERT_TRUE(volume::writeNrrd(labels, path("labels.nrrd")).ok());
  std::ofstream(path("labels.ctbl")) << "# Slicer colour table\n0 Background 0 0 0 0\n"
                                     << "3 Rectum 200 100 50 255\n7 Urethra 255 255 0 255\n";
  const auto read = readStructures(path("labels.nrrd"), {});
  ASSERT_TRUE(read.ok()) << read.error().message;
  ASSERT_EQ(read->structures.size(), 2u);
  EXPECT_EQ(read->structures[0].name, "Rectum");
  EXPECT_NEAR(read->structures[0].colour_rgb[0], 200.0 / 255.0, 1e-12);
  expectSameMask(read->structures[1].mask, set.find("urethra")->mask);
  // The site gives roles by name, ignoring case.
  std::ofstream(path("site.yaml")) << "site: prostate\nstructures:\n"
                                   << "  - {name: urethra, role: avoid, margin_mm: 3}\n"
                                   << "  - {name: rectum_wall, aliases: [rectum], role: avoid, "
                                      "margin_mm: 5}\n";
  const auto site = readSite(path("site.yaml"));
  ASSERT_TRUE(site.ok()) << site.error().message;
  auto roles = *read;
  applySite(*site, roles);
  EXPECT_EQ(roles.find("urethra")->role, Role::kAvoid);
  EXPECT_EQ(roles.find("RECTUM")->margin_mm, 5.0);
}

void expectRefused(const Expected<StructureSet>& got, const std::string& reason,
                   const std::string& says) {
  ASSERT_FALSE(got.ok());
  EXPECT_EQ(got.error().reason, reason) << got.error().message;
  EXPECT_NE(got.error().message.find(says), std::string::npos) << got.error().message;
}

TEST_F(Structures, BadSegmentationsAreRefusedByName) {
  volume::NrrdLayers image;
  image.geometry = ct_;
  image.values.assign(ct_.voxelCount(), 0);
  image.values[100] = 1;
  image.values[200] = 2;
  const auto write = [&](const std::string& name,
                         std::vector<std::pair<std::string, std::string>> kv) {
    image.key_values = std::move(kv);
    EXPECT_TRUE(volume::writeNrrdLayers(image, path(name)).ok());
    return readSegNrrd(path(name));
  };
  const auto segment = [](int n, const std::string& name, int label) {
    std::vector<std::pair<std::string, std::string>> kv = {
        {"Segment" + std::to_string(n) + "_ID", "s" + std::to_string(n)},
        {"Segment" + std::to_string(n) + "_LabelValue", std::to_string(label)},
        {"Segment" + std::to_string(n) + "_Layer", "0"}};
    if (!name.empty()) kv.emplace_back("Segment" + std::to_string(n) + "_Name", name);
    return kv;
  };
  auto two = segment(0, "a", 1);
  for (auto& kv : segment(1, "b", 2))
    two.push_back(kv);
  EXPECT_TRUE(write("ok.seg.nrrd", two).ok());
  // A segment whose label no voxel carries.
  auto empty = two;
  empty[5].second = "9";
  expectRefused(write("empty.seg.nrrd", empty), "empty_structure", "segment 1 'b'");
  // Voxels of a label no segment describes.
  expectRefused(write("stray.seg.nrrd", segment(0, "a", 1)), "label_out_of_range",
                "label 2 in layer 0 belongs to no segment");
  // A label value out of range, a layer that does not exist, a missing name.
  auto big = two;
  big[1].second = "40000";
  expectRefused(write("big.seg.nrrd", big), "label_out_of_range", "label value '40000'");
  auto layer = two;
  layer[2].second = "3";
  expectRefused(write("layer.seg.nrrd", layer), "label_out_of_range", "layer 3 does not exist");
  auto unnamed = segment(0, "a", 1);
  for (auto& kv : segment(1, "", 2))
    unnamed.push_back(kv);
  expectRefused(write("unnamed.seg.nrrd", unnamed), "names_missing", "segment 1 has no name");
  expectRefused(write("none.seg.nrrd", {}), "names_missing", "no segment is described");
  // ignav's own tags: a role it does not know, a margin that is no distance or beyond 10 mm (as
  // the site file and structure_role would refuse it).
  for (const auto& [tags, says] : std::vector<std::pair<std::string, std::string>>{
           {"ignav.role:shield|", "role 'shield' is unknown"},
           {"ignav.role:avoid|ignav.margin_mm:3mm|", "margin '3mm' is not a distance"},
           {"ignav.role:avoid|ignav.margin_mm:15|", "margin 15 mm is outside 0-10 mm"}}) {
    auto tagged = two;
    tagged.emplace_back("Segment1_Tags", tags);
    expectRefused(write("tagged.seg.nrrd", tagged), "bad_segment", says);
  }
  auto ten = two;
  ten.emplace_back("Segment1_Tags", "ignav.role:avoid|ignav.margin_mm:10|");
  ASSERT_TRUE(write("ten.seg.nrrd", ten).ok());
  EXPECT_EQ(write("ten.seg.nrrd", ten)->structures[1].margin_mm, 10.0);
  // A label map without its colour table, or with a label it does not name.
  volume::Volume labels;
  labels.geometry = ct_;
  labels.voxels.assign(ct_.voxelCount(), 0);
  labels.voxels[5] = 4;
  ASSERT_TRUE(volume::writeNrrd(labels, path("l.nrrd")).ok());
  expectRefused(readStructures(path("l.nrrd"), {}), "names_missing", "needs a colour table");
  std::ofstream(path("l.ctbl")) << "1 prostate 1 2 3 255\n";
  expectRefused(readStructures(path("l.nrrd"), {}), "names_missing", "label 4 is not named");
  EXPECT_EQ(readStructures(path("x.vtk"), {}).error().reason, "unsupported");
}

TEST_F(Structures, ASegmentationOfAnotherCtIsRefusedSayingHowItDiffers) {
  const auto set = anatomy();
  ASSERT_TRUE(checkOnCt(set, ct_, "ct").ok());
  auto other = ct_;
  other.spacing_mm.z() = 2.0;
  auto refused = checkOnCt(set, other, "ct");
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().reason, "other_ct");
  EXPECT_NE(refused.error().message.find("'prostate'"), std::string::npos);
  other = ct_;
  other.origin_lps_mm.x() += 0.3;  // a shift of part of a voxel
  refused = checkOnCt(set, other, "ct");
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("voxels off the CT's"), std::string::npos);
  other = ct_;
  other.dims[1] = 22;  // the rectum lies beyond this CT
  refused = checkOnCt(set, other, "ct");
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("'rectum'"), std::string::npos);
}

TEST_F(Structures, ABadSiteFileNamesTheEntry) {
  std::ofstream(path("s.yaml")) << "structures:\n  - {name: urethra, role: avoid}\n";
  auto site = readSite(path("s.yaml"));
  ASSERT_FALSE(site.ok());
  EXPECT_NE(site.error().message.find("structures[0] (urethra): an avoided structure needs "
                                      "margin_mm"),
            std::string::npos);
  std::ofstream(path("s.yaml")) << "structures:\n  - {name: urethra, role: dodge}\n";
  EXPECT_NE(readSite(path("s.yaml")).error().message.find("role 'dodge'"), std::string::npos);
  std::ofstream(path("s.yaml"))
      << "structures:\n  - {name: urethra, role: avoid, margin_mm: .nan}\n";
  EXPECT_NE(readSite(path("s.yaml")).error().message.find("outside 0-10 mm"), std::string::npos);
}

// Seed plans (issue 42): the prostate site's dose limits and its dosimetry block, and bad ones
// named by their field.
TEST_F(Structures, ASiteGivesDoseLimitsAndSeedPlanDefaults) {
  const auto prostate = readSite(IGNAV_SOURCE_DIR "/configs/sites/prostate.yaml");
  ASSERT_TRUE(prostate.ok()) << prostate.error().message;
  EXPECT_EQ(prostate->roleFor("urethra")->dose_limits.d10_percent, 150.0);
  EXPECT_EQ(prostate->roleFor("rectal_wall")->dose_limits.d2cc_percent, 100.0);
  EXPECT_FALSE(prostate->roleFor("prostate")->dose_limits.any());
  ASSERT_TRUE(prostate->dosimetry.has_value());
  EXPECT_EQ(prostate->dosimetry->seed_models,
            (std::vector<std::string>{"oncura_6711", "theraseed_200"}));
  EXPECT_EQ(prostate->dosimetry->seed_model, "oncura_6711");
  EXPECT_EQ(prostate->dosimetry->prescription_Gy, 145.0);

  auto refused = [&](const std::string& text) {
    std::ofstream(path("s.yaml")) << text;
    const auto site = readSite(path("s.yaml"));
    return site.ok() ? std::string("accepted") : site.error().message;
  };
  const std::string models = "dosimetry: {seed_models: " IGNAV_SOURCE_DIR "/configs/seeds";
  const std::string urethra = "structures:\n  - {name: urethra, role: avoid, margin_mm: 3";
  EXPECT_NE(refused(urethra + ", dose_limits: {d10_percent: -3}}\n")
                .find("structures[0] (urethra): dose_limits.d10_percent = -3 is outside 0-1000 %"),
            std::string::npos);
  EXPECT_NE(refused(urethra + ", dose_limits: {d15_percent: 3}}\n")
                .find("dose_limits.d15_percent is none of"),
            std::string::npos);
  EXPECT_NE(refused("structures: []\ndosimetry: {seed_models: nowhere}\n")
                .find("dosimetry.seed_models: '"),
            std::string::npos);
  EXPECT_NE(refused("structures: []\n" + models + ", seed_model: iridium}\n")
                .find("dosimetry.seed_model 'iridium' is none of oncura_6711, theraseed_200"),
            std::string::npos);
  EXPECT_NE(refused("structures: []\n" + models + ", seed_model: oncura_6711, strength_U: 40}\n")
                .find("dosimetry.strength_U = 40 is outside"),
            std::string::npos);
  EXPECT_NE(
      refused("structures: []\n" + models + ", seed_model: oncura_6711, prescription_Gy: 0}\n")
          .find("dosimetry.prescription_Gy = 0 is outside"),
      std::string::npos);
}

}  // namespace
}  // namespace ignav::anatomy
