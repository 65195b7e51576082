// The seeds as a DICOM RT Plan (issue 42, part 5) against third parties: pydicom reads back the
// source, the prescription and each seed's position (tests/dosimetry/rt_plan_reference.py), and
// David Clunie's dciodvfy (Debian's dicom3tools) checks the plan and an RT Dose that names it
// against their IODs. Also the DVH plot: its curves where its axes put them.
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "ignav/dosimetry/dvh_plot.hpp"
#include "ignav/dosimetry/rt_dose.hpp"
#include "ignav/dosimetry/rt_plan.hpp"
#include "support/command_output.hpp"
#include "support/dciodvfy.hpp"

namespace ignav::dosimetry {
namespace {
namespace fs = std::filesystem;

using test::commandOutput;

const std::string kReader = IGNAV_SOURCE_DIR "/tests/dosimetry/rt_plan_reference.py";

SeedModel model6711() {
  return readSeedModel(IGNAV_SOURCE_DIR "/configs/seeds/oncura_6711.yaml").value();
}

TEST(RtPlan, PydicomReadsTheSeedsAndDciodvfyFindsNoError) {
  const auto dir = fs::temp_directory_path() / "ignav_rt_plan_test";
  fs::create_directories(dir);
  const std::vector<Seed> seeds = {{{1.5, -20.25, 33.0}, {0, 0, 1}},
                                   {{-7.125, 4.0, 12.5}, {0, 0.6, 0.8}},
                                   {{0.0, 0.0, -9.75}, {1, 0, 0}}};
  RtPlanHeader header;
  header.frame_of_reference_uid = "1.2.826.0.1.3680043.8.498.42.7";
  header.structure_set_uid = newDicomUid();
  header.patient_name = "IGNAV^TEST";
  header.patient_id = "T1";
  header.date_yyyymmdd = "20261129";
  header.time_hhmmss = "101500";
  const std::string path = (dir / "plan.dcm").string();
  const auto model = model6711();
  ASSERT_TRUE(writeSeedRtPlan(seeds, model, 0.6, 145.0, header, path).ok());

  const auto read =
      nlohmann::json::parse(commandOutput("/usr/bin/python3 " + kReader + " plan " + path));
  EXPECT_EQ(read.at("sop_class"), "1.2.840.10008.5.1.4.1.1.481.5");  // RT Plan Storage
  EXPECT_EQ(read.at("modality"), "RTPLAN");
  EXPECT_EQ(read.at("technique"), "PERMANENT");
  EXPECT_EQ(read.at("type"), "LDR");
  EXPECT_EQ(read.at("isotope"), "I-125");
  EXPECT_NEAR(read.at("half_life_days").get<double>(), 59.40, 1e-6);  // the model file's
  EXPECT_NEAR(read.at("air_kerma_rate").get<double>(), 0.6, 1e-9);
  EXPECT_NEAR(read.at("active_length_mm").get<double>(), 3.0, 1e-9);
  EXPECT_EQ(read.at("model"), "oncura_6711");
  EXPECT_NEAR(read.at("prescription_gy").get<double>(), 145.0, 1e-9);
  EXPECT_EQ(read.at("frame_of_reference"), header.frame_of_reference_uid);
  EXPECT_EQ(read.at("structure_set"), header.structure_set_uid);
  ASSERT_EQ(read.at("seeds").size(), seeds.size());
  for (std::size_t n = 0; n < seeds.size(); ++n)
    for (int a = 0; a < 3; ++a)
      EXPECT_NEAR(read.at("seeds")[n][a].get<double>(), seeds[n].centre_lps_mm[a], 1e-4);
  EXPECT_EQ(test::iodErrors(path, "RTPlan"), std::vector<std::string>{});

  // An RT Dose naming the plan: valid too. (dciodvfy aborts on 32-bit pixel data, which RT Dose
  // allows; its attributes are then checked on a copy whose pixel description dcmodify sets to
  // 16 bits, every other attribute as written.)
  volume::Geometry grid;
  grid.dims = {4, 3, 2};
  RtDoseHeader dose;
  dose.frame_of_reference_uid = header.frame_of_reference_uid;
  dose.plan_uid = newDicomUid();
  const std::string dose_path = (dir / "dose.dcm").string();
  ASSERT_TRUE(writeRtDose(std::vector<float>(24, 2.5f), grid, dose, dose_path).ok());
  EXPECT_EQ(test::iodErrors(test::readableByDciodvfy(dose_path), "RTDose"),
            std::vector<std::string>{});
}

TEST(RtPlan, BadPlansAreRefusedNamingWhat) {
  const auto path = (fs::temp_directory_path() / "ignav_bad_plan.dcm").string();
  const auto model = model6711();
  const Seed good{{0, 0, 0}, {0, 0, 1}};
  EXPECT_EQ(writeSeedRtPlan({}, model, 0.6, 145.0, {}, path).error().reason, "bad_plan");
  const Seed nowhere{{0, std::nan(""), 0}, {0, 0, 1}};
  const auto bad = writeSeedRtPlan({good, nowhere}, model, 0.6, 145.0, {}, path);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("seed 2"), std::string::npos) << bad.error().message;
  EXPECT_EQ(writeSeedRtPlan({good}, model, 0.0, 145.0, {}, path).error().reason, "bad_plan");
  EXPECT_EQ(writeSeedRtPlan({good}, model, 0.6, -1.0, {}, path).error().reason, "bad_plan");
  EXPECT_EQ(
      writeSeedRtPlan({good}, model, 0.6, 145.0, {}, "/nonexistent/dir/plan.dcm").error().code,
      ErrorCode::kIo);
}

// A step DVH (everything up to 100 Gy, nothing beyond): its colour on the top edge up to the
// step and not after it, where the layout's axes put those doses.
TEST(DvhPlot, ACurveIsDrawnWhereTheAxesPutIt) {
  DvhCurve step{"step", {200, 30, 30}, false, 1.0, std::vector<double>(101, 1.0)};
  step.cumulative.push_back(0.0);
  const auto layout = dvhPlotLayout({step}, 145.0);
  ASSERT_TRUE(layout.ok());
  EXPECT_EQ(layout->max_Gy, 150.0);  // the prescription, rounded up to 50 Gy
  const auto png = dvhPlotPng({step}, 145.0);
  ASSERT_TRUE(png.ok()) << png.error().message;
  const cv::Mat img = cv::imdecode(
      cv::Mat(1, static_cast<int>(png->size()), CV_8UC1, const_cast<std::uint8_t*>(png->data())),
      cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, layout->width_px);
  ASSERT_EQ(img.rows, layout->height_px);
  auto is_curve = [&](double dose, double fraction) {
    const cv::Vec3b bgr = img.at<cv::Vec3b>(static_cast<int>(std::lround(layout->y(fraction))),
                                            static_cast<int>(std::lround(layout->x(dose))));
    return bgr[2] == 200 && bgr[1] == 30 && bgr[0] == 30;
  };
  EXPECT_TRUE(is_curve(50.0, 1.0));
  EXPECT_TRUE(is_curve(99.0, 1.0));
  EXPECT_FALSE(is_curve(120.0, 1.0));
  bool drop = false;  // the fall from 100 % to 0 between 100 and 101 Gy, halfway down
  for (double dose = 99.5; dose <= 101.5; dose += 0.1)
    drop = drop || is_curve(dose, 0.5);
  EXPECT_TRUE(drop);
  EXPECT_TRUE(is_curve(101.0, 0.0));  // its last bin
  EXPECT_FALSE(is_curve(130.0, 0.5));

  DvhCurve broken = step;
  broken.cumulative[3] = 1.5;
  EXPECT_EQ(dvhPlotLayout({broken}, 145.0).error().reason, "bad_plot");
  EXPECT_EQ(dvhPlotLayout({}, 145.0).error().reason, "bad_plot");
  EXPECT_EQ(dvhPlotLayout({step}, 0.0).error().reason, "bad_plot");
}

}  // namespace
}  // namespace ignav::dosimetry
