// The dose written as a DICOM RT Dose (issue 42, part 5) and the histograms of part 2 against a
// third party: dicompyler-core (Debian's python3-dicompylercore) reads ignav's RT Dose and RT
// Structure Set and computes each structure's DVH; its volume, D90 and V100 against ignav's from
// the structure's voxels (tests/dosimetry/dvh_reference.py).
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "ignav/anatomy/dicom_structures.hpp"
#include "ignav/dosimetry/dose_grid.hpp"
#include "ignav/dosimetry/dvh.hpp"
#include "ignav/dosimetry/rt_dose.hpp"
#include "support/command_output.hpp"

namespace ignav::dosimetry {
namespace {
namespace fs = std::filesystem;

const std::string kReference = IGNAV_SOURCE_DIR "/tests/dosimetry/dvh_reference.py";

using test::commandOutput;

// The doses at a structure's voxels (its mask lies on the dose grid's voxels: the CT's).
std::vector<double> dosesIn(const anatomy::Structure& s, const volume::Geometry& grid,
                            const std::vector<float>& dose_Gy) {
  std::vector<double> out;
  const auto& g = s.mask.geometry;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i) {
        if (!s.mask.inside[s.mask.index(i, j, k)]) continue;
        const Eigen::Vector3d ijk = grid.toIjk(g.toLps(Eigen::Vector3d(i, j, k))).array().round();
        out.push_back(
            dose_Gy[anatomy::gridIndex(grid.dims, static_cast<int>(ijk.x()),
                                       static_cast<int>(ijk.y()), static_cast<int>(ijk.z()))]);
      }
  return out;
}

TEST(RtDose, DicompylerCoreReadsTheSameHistogramsFromTheExportedFiles) {
  volume::Geometry ct;  // axial, 1 mm pixels, 1.5 mm slices
  ct.dims = {72, 70, 44};
  ct.spacing_mm = Eigen::Vector3d(1.0, 1.0, 1.5);
  ct.origin_lps_mm = Eigen::Vector3d(-35.5, -34.5, -32.0);
  const auto set = anatomy::voxelise(
      ct, Eigen::Matrix4d::Identity(),
      {{"prostate",
        {0.85, 0.6, 0.4},
        anatomy::Role::kTarget,
        0.0,
        [](const Eigen::Vector3d& p) { return p.norm() - 18.0; }},
       {"urethra",
        {1, 0.9, 0.2},
        anatomy::Role::kAvoid,
        3.0,
        [](const Eigen::Vector3d& p) { return std::hypot(p.x() - 4.0, p.y() + 2.0) - 3.5; }}},
      "test");
  ASSERT_TRUE(set.ok()) << set.error().message;

  // Seeds on a 9 mm lattice in the gland, none within 4 mm of the urethra's axis; I-125 6711 at
  // 0.5 U, the permanent implant's dose.
  const auto table = DoseRateTable::make(
      readSeedModel(IGNAV_SOURCE_DIR "/configs/seeds/oncura_6711.yaml").value());
  ASSERT_TRUE(table.ok());
  std::vector<Seed> seeds;
  for (int x = -1; x <= 1; ++x)
    for (int y = -1; y <= 1; ++y)
      for (int z = -1; z <= 1; ++z) {
        const Eigen::Vector3d c(9.0 * x + 1.0, 9.0 * y, 9.0 * z);
        if (std::hypot(c.x() - 4.0, c.y() + 2.0) > 4.0)
          seeds.push_back({c, Eigen::Vector3d::UnitZ()});
      }
  ASSERT_EQ(seeds.size(), 24u);  // three lattice points lie by the urethra
  const auto rates = doseRateOnGrid(*table, seeds, 0.5, ct, 2);
  std::vector<float> dose_Gy(rates.size());
  for (std::size_t v = 0; v < rates.size(); ++v)
    dose_Gy[v] =
        static_cast<float>(permanentImplantDose_cGy(rates[v], table->model().half_life_h) / 100.0);

  const auto dir = fs::temp_directory_path() / "ignav_rt_dose_test";
  fs::create_directories(dir);
  const std::string frame = "1.2.826.0.1.3680043.8.498.42.1";
  ASSERT_TRUE(anatomy::writeRtStructureSet(*set, {ct, frame, "test CT"}, {},
                                           (dir / "rtstruct.dcm").string())
                  .ok());
  RtDoseHeader header;
  header.frame_of_reference_uid = frame;
  ASSERT_TRUE(writeRtDose(dose_Gy, ct, header, (dir / "rtdose.dcm").string()).ok());

  // The prescription: about where our target's D93 lies, so that V100 is neither 0 nor 1.
  const auto target =
      DoseVolumeHistogram::of(dosesIn(*set->find("prostate"), ct, dose_Gy), 0.0015).value();
  const double rx_Gy = std::round(target.doseToHottestFraction_Gy(0.93));
  const auto theirs = nlohmann::json::parse(
      commandOutput("/usr/bin/python3 " + kReference + " dvh " + (dir / "rtstruct.dcm").string() +
                    " " + (dir / "rtdose.dcm").string() + " " + std::to_string(rx_Gy)));
  for (const auto& s : set->structures) {
    const auto ours = DoseVolumeHistogram::of(dosesIn(s, ct, dose_Gy), 0.0015).value();
    ASSERT_TRUE(theirs.contains(s.name)) << theirs.dump();
    const auto& t = theirs.at(s.name);
    EXPECT_NEAR(t.at("volume_cm3").get<double>() / ours.volume_cm3(), 1.0, 0.01) << s.name;
    EXPECT_NEAR(t.at("d90_gy").get<double>() / ours.doseToHottestFraction_Gy(0.9), 1.0, 0.01)
        << s.name;
    EXPECT_NEAR(t.at("v100").get<double>(), ours.fractionAtLeast(rx_Gy), 0.01) << s.name;
    std::printf("%s: %.2f cm³ (theirs %.2f), D90 %.1f Gy (%.1f), V%.0fGy %.3f (%.3f)\n",
                s.name.c_str(), ours.volume_cm3(), t.at("volume_cm3").get<double>(),
                ours.doseToHottestFraction_Gy(0.9), t.at("d90_gy").get<double>(), rx_Gy,
                ours.fractionAtLeast(rx_Gy), t.at("v100").get<double>());
  }
}

TEST(RtDose, BadDosesAndGridsAreRefused) {
  volume::Geometry g;
  g.dims = {2, 2, 2};
  const auto path = (fs::temp_directory_path() / "ignav_bad_dose.dcm").string();
  EXPECT_EQ(writeRtDose(std::vector<float>(7, 1.0f), g, {}, path).error().reason, "bad_dose");
  std::vector<float> doses(8, 1.0f);
  doses[3] = -1.0f;
  EXPECT_NE(writeRtDose(doses, g, {}, path).error().message.find("voxel 3"), std::string::npos);
  g.direction.col(2) *= -1.0;  // frames stacked against the normal
  EXPECT_EQ(writeRtDose(std::vector<float>(8, 1.0f), g, {}, path).error().reason, "bad_dose");
}

}  // namespace
}  // namespace ignav::dosimetry
