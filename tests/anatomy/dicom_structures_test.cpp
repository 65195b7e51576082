// Structures from DICOM (issue 41) against third parties: pydicom's own rtstruct.dcm, RT
// Structure Sets written by pydicom (rings with holes, several contours per slice, a concave
// star, a sphere) whose volumes dicompyler-core (its DVH over an RT Dose on the CT's grid) and
// plastimatch (its rasterisation onto the CT) compute independently, closed-form areas, a DICOM
// SEG made by DCMTK's dcmseg read back voxel for voxel, and every bad input refused by name.
#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmfg/fgfracon.h>
#include <dcmtk/dcmfg/fgpixmsr.h>
#include <dcmtk/dcmfg/fgplanor.h>
#include <dcmtk/dcmfg/fgplanpo.h>
#include <dcmtk/dcmfg/fgseg.h>
#include <dcmtk/dcmiod/cielabutil.h>
#include <dcmtk/dcmseg/segdoc.h>
#include <dcmtk/dcmseg/segment.h>
#include <dcmtk/dcmseg/segutils.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>

#include "ignav/anatomy/dicom_structures.hpp"
#include "ignav/volume/image_io.hpp"
#include "support/command_output.hpp"

namespace ignav::anatomy {
namespace {
namespace fs = std::filesystem;

const std::string kPydicomRtStruct =
    "/usr/lib/python3/dist-packages/pydicom/data/test_files/rtstruct.dcm";
const std::string kReference =
    std::string(IGNAV_SOURCE_DIR) + "/tests/anatomy/rtstruct_reference.py";
// The frame of reference rtstruct.dcm's ROIs name.
const std::string kPydicomFrame = "1.2.826.0.1.3680043.8.498.2010020400001.2";

using test::commandOutput;

std::string gridJson(const volume::Geometry& g) {
  nlohmann::json j;
  j["origin"] = {g.origin_lps_mm.x(), g.origin_lps_mm.y(), g.origin_lps_mm.z()};
  j["spacing"] = {g.spacing_mm.x(), g.spacing_mm.y(), g.spacing_mm.z()};
  j["dims"] = {g.dims[0], g.dims[1], g.dims[2]};
  return j.dump();
}

class DicomStructures : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("ignav_dicom_structures_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    // A CT like the phantom's (0.8 x 0.8 x 1.25 mm), its centres off the shapes' symmetry.
    ct_.geometry.dims = {96, 96, 64};
    ct_.geometry.spacing_mm = Eigen::Vector3d(0.8, 0.8, 1.25);
    ct_.geometry.origin_lps_mm = Eigen::Vector3d(-37.6, -37.6, -39.375);
    ct_.frame_of_reference_uid = "1.2.826.0.1.3680043.9.7133.41.1";
    ct_.name = "test CT";
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // The grid as a CT NRRD of zeros: plastimatch's --fixed image.
  std::string ctNrrd(const volume::Geometry& g) const {
    volume::Volume v;
    v.geometry = g;
    v.voxels.assign(g.voxelCount(), 0);
    const std::string p = path("ct.nrrd");
    EXPECT_TRUE(volume::writeNrrd(v, p).ok());
    return p;
  }
  // plastimatch's masks of every structure of `rtstruct` on grid `g`, by name. --xor-contours:
  // a contour inside another is a hole, as DICOM RT means it (plastimatch ORs them by default).
  std::map<std::string, volume::Volume> plastimatch(const std::string& rtstruct,
                                                    const volume::Geometry& g) const {
    const std::string out = path("plastimatch");
    commandOutput("plastimatch convert --input " + rtstruct + " --fixed " + ctNrrd(g) +
                  " --xor-contours --output-prefix " + out +
                  " --prefix-format nrrd >/dev/null 2>&1");
    std::map<std::string, volume::Volume> masks;
    if (!fs::exists(out)) {
      ADD_FAILURE() << "plastimatch wrote nothing: tools/setup.sh installs it";
      return masks;
    }
    for (const auto& e : fs::directory_iterator(out)) {
      auto v = volume::readNrrd(e.path().string());
      EXPECT_TRUE(v.ok()) << e.path();
      if (v) masks[e.path().stem().string()] = std::move(v).value();
    }
    return masks;
  }
  nlohmann::json dicompyler(const std::string& rtstruct, const volume::Geometry& g) const {
    return nlohmann::json::parse(commandOutput("/usr/bin/python3 " + kReference + " volumes " +
                                               rtstruct + " '" + gridJson(g) + "'"));
  }

  fs::path dir_;
  CtFrame ct_;
};

std::size_t countSet(const volume::Volume& v) {
  std::size_t n = 0;
  for (const auto x : v.voxels)
    n += x != 0;
  return n;
}

// Voxels where our mask and plastimatch's (on the whole CT) differ.
std::size_t differing(const Mask& mine, const volume::Volume& theirs) {
  std::size_t diff = 0, n = 0;
  const auto& g = theirs.geometry;
  for (int k = 0; k < g.dims[2]; ++k)
    for (int j = 0; j < g.dims[1]; ++j)
      for (int i = 0; i < g.dims[0]; ++i, ++n) {
        const Eigen::Vector3d at = mine.geometry.toIjk(g.toLps(Eigen::Vector3d(i, j, k)));
        diff += mine.insideNearest(at) != (theirs.voxels[n] != 0);
      }
  return diff;
}

TEST_F(DicomStructures, PydicomsStructureSetMatchesDicompylerAndPlastimatch) {
  ASSERT_TRUE(fs::exists(kPydicomRtStruct)) << "tools/setup.sh installs python3-pydicom";
  // A CT under its contours (400 x 300 mm rectangles at z -200, -190, -180), centres off their
  // edges, in the frame of reference the file names.
  CtFrame ct;
  ct.geometry.dims = {220, 160, 3};
  ct.geometry.spacing_mm = Eigen::Vector3d(2, 2, 10);
  ct.geometry.origin_lps_mm = Eigen::Vector3d(-219, -159, -200);
  ct.frame_of_reference_uid = kPydicomFrame;
  ct.name = "pydicom's CT";
  auto set = readStructures(kPydicomRtStruct, ct);
  ASSERT_TRUE(set.ok()) << set.error().message;
  ASSERT_EQ(set->structures.size(), 1u);
  const Structure& patient = set->structures[0];
  EXPECT_EQ(patient.name, "patient");
  EXPECT_NEAR(patient.colour_rgb[0], 220 / 255.0, 1e-9);  // ROIDisplayColor 220\160\120
  EXPECT_NEAR(patient.colour_rgb[2], 120 / 255.0, 1e-9);
  // The isocentres are points: named in the notes, not structures.
  ASSERT_EQ(set->notes.size(), 2u);
  EXPECT_NE(set->notes[0].find("'Isocenter 1' holds points or open contours only"),
            std::string::npos);

  const double reference = dicompyler(kPydicomRtStruct, ct.geometry)["patient"];
  EXPECT_NEAR(patient.mask.volume_cm3(), reference, 0.03 * reference);
  const auto theirs = plastimatch(kPydicomRtStruct, ct.geometry);
  ASSERT_EQ(theirs.count("patient"), 1u);
  const double plastimatch_cm3 =
      static_cast<double>(countSet(theirs.at("patient"))) * ct.geometry.spacing_mm.prod() / 1000.0;
  EXPECT_NEAR(patient.mask.volume_cm3(), plastimatch_cm3, 0.03 * plastimatch_cm3);
  // By closed form too: 400 x 300 mm on three 10 mm slices.
  EXPECT_NEAR(patient.mask.volume_cm3(), 3 * 400.0 * 300.0 * 10.0 / 1000.0, 1e-9);
}

TEST_F(DicomStructures, HolesIslandsAndConcaveContoursMatchDicompylerAndPlastimatch) {
  const std::string file = path("shapes.dcm");
  commandOutput("/usr/bin/python3 " + kReference + " make " + file + " " +
                ct_.frame_of_reference_uid + " '" + gridJson(ct_.geometry) + "'");
  auto set = readStructures(file, ct_);
  ASSERT_TRUE(set.ok()) << set.error().message;
  ASSERT_EQ(set->structures.size(), 4u);
  ASSERT_EQ(set->notes.size(), 1u);  // the marker
  const auto reference = dicompyler(file, ct_.geometry);
  const auto theirs = plastimatch(file, ct_.geometry);
  // Closed forms: the areas times the slices drawn (1.25 mm each).
  const double pi = std::acos(-1.0);
  const std::map<std::string, double> closed_cm3{
      {"ring", pi * (20.0 * 20 - 8.0 * 8) * 20 * 1.25 / 1000},
      {"islands", 2 * pi * 36.0 * 20 * 1.25 / 1000},
      {"ball", 4.0 / 3 * pi * std::pow(14.0, 3) / 1000}};
  for (const auto& s : set->structures) {
    SCOPED_TRACE(s.name);
    const double mine = s.mask.volume_cm3();
    const double dicompyler_cm3 = reference.at(s.name);
    EXPECT_NEAR(mine, dicompyler_cm3, 0.03 * dicompyler_cm3);
    ASSERT_EQ(theirs.count(s.name), 1u);
    const double plastimatch_cm3 =
        static_cast<double>(countSet(theirs.at(s.name))) * ct_.geometry.spacing_mm.prod() / 1000.0;
    EXPECT_NEAR(mine, plastimatch_cm3, 0.03 * plastimatch_cm3);
    // Voxel for voxel, the two rasterisations differ only where an edge passes a centre.
    EXPECT_LT(static_cast<double>(differing(s.mask, theirs.at(s.name))),
              0.03 * static_cast<double>(s.mask.count()));
    if (closed_cm3.count(s.name)) {
      EXPECT_NEAR(mine, closed_cm3.at(s.name), 0.02 * mine);
    }
  }
  // The ring's hole is empty, its wall full; the islands are apart.
  const Structure* ring = set->find("ring");
  auto at = [&](const Structure& s, double x, double y, double z) {
    return s.mask.insideNearest(s.mask.geometry.toIjk(Eigen::Vector3d(x, y, z)));
  };
  EXPECT_FALSE(at(*ring, 5.3, -3.1, 0.625));
  EXPECT_TRUE(at(*ring, 5.3 + 14, -3.1, 0.625));
  const Structure* islands = set->find("islands");
  EXPECT_TRUE(at(*islands, -29.7, 20.2, 0.625));
  EXPECT_FALSE(at(*islands, -21.0, 20.4, 0.625));
}

// Polygons on one slice, straight from the rasteriser: squares whose voxels are countable.
TEST_F(DicomStructures, RasterisesEvenOddByVoxelCentres) {
  const volume::Geometry& g = ct_.geometry;
  auto square = [&](double i0, double j0, double i1, double j1, double k, bool reverse) {
    PlanarContour c;
    std::vector<Eigen::Vector3d> ijk{{i0, j0, k}, {i1, j0, k}, {i1, j1, k}, {i0, j1, k}};
    if (reverse) std::reverse(ijk.begin(), ijk.end());
    for (const auto& p : ijk)
      c.points_lps_mm.push_back(g.toLps(p));
    return c;
  };
  // 20 x 20 centres, a 6 x 6 hole (drawn either way round), a 3 x 3 island in the hole.
  auto mask = rasteriseContours(
      {square(9.5, 9.5, 29.5, 29.5, 5, false), square(16.5, 16.5, 22.5, 22.5, 5, true),
       square(18.5, 18.5, 21.5, 21.5, 5, false), square(9.5, 9.5, 12.5, 11.5, 6, false)},
      g, "squares");
  ASSERT_TRUE(mask.ok()) << mask.error().message;
  EXPECT_EQ(mask->count(), 20u * 20 - 36 + 9 + 3 * 2);
}

TEST_F(DicomStructures, BadContoursAreRefusedByName) {
  const volume::Geometry& g = ct_.geometry;
  auto contour = [&](std::vector<Eigen::Vector3d> ijk) {
    PlanarContour c;
    for (const auto& p : ijk)
      c.points_lps_mm.push_back(g.toLps(p));
    return c;
  };
  auto refused = [](const Expected<Mask>& m, const std::string& reason, const std::string& says) {
    ASSERT_FALSE(m.ok());
    EXPECT_EQ(m.error().reason, reason) << m.error().message;
    EXPECT_NE(m.error().message.find(says), std::string::npos) << m.error().message;
  };
  // A bow tie crosses itself at its middle, (20, 20) on slice 3.
  const auto bow = rasteriseContours(
      {contour({{10, 10, 3}, {30, 30, 3}, {30, 10, 3}, {10, 30, 3}})}, g, "urethra");
  const Eigen::Vector3d middle = g.toLps(Eigen::Vector3d(20, 20, 3));
  refused(bow, "self_intersecting",
          fmt::format("urethra: contour 1 crosses itself at ({:.2f}, {:.2f}, {:.2f})", middle.x(),
                      middle.y(), middle.z()));
  // Between slices, tilted across them, beyond the CT, too few points, not finite.
  refused(rasteriseContours({contour({{10, 10, 3.4}, {20, 10, 3.4}, {20, 20, 3.4}})}, g, "a"),
          "other_ct", "does not lie in one of the CT's slices");
  refused(rasteriseContours({contour({{10, 10, 3}, {20, 10, 4}, {20, 20, 3}})}, g, "a"), "other_ct",
          "does not lie in one of the CT's slices");
  refused(rasteriseContours({contour({{10, 10, 64}, {20, 10, 64}, {20, 20, 64}})}, g, "a"),
          "other_ct", "beyond the CT");
  refused(rasteriseContours({contour({{-3, 10, 3}, {20, 10, 3}, {20, 20, 3}})}, g, "a"), "other_ct",
          "beyond the CT");
  refused(rasteriseContours({contour({{10, 10, 3}, {20, 10, 3}, {10, 10, 3}})}, g, "a"), "format",
          "fewer than three distinct points");
  refused(rasteriseContours({contour({{10, 10, 3}, {NAN, 10, 3}, {20, 20, 3}})}, g, "a"), "format",
          "not finite");
  // Smaller than a voxel, between centres.
  refused(rasteriseContours({contour({{10.1, 10.1, 3}, {10.4, 10.1, 3}, {10.4, 10.4, 3}})}, g, "a"),
          "empty_structure", "enclose no voxel centre");
  // A keyhole (a hole joined to the outside by a cut of no width) is not a crossing.
  auto keyhole = rasteriseContours({contour({{10, 10, 3},
                                             {30, 10, 3},
                                             {30, 30, 3},
                                             {20, 30, 3},
                                             {20, 25, 3},
                                             {25, 25, 3},
                                             {25, 15, 3},
                                             {15, 15, 3},
                                             {15, 25, 3},
                                             {20, 25, 3},
                                             {20, 30, 3},
                                             {10, 30, 3}})},
                                   g, "keyhole");
  EXPECT_TRUE(keyhole.ok()) << keyhole.error().message;
}

TEST_F(DicomStructures, AStructureSetOfAnotherFrameIsRefused) {
  const std::string file = path("shapes.dcm");
  commandOutput("/usr/bin/python3 " + kReference + " make " + file + " 1.2.3.999 '" +
                gridJson(ct_.geometry) + "'");
  auto set = readStructures(file, ct_);
  ASSERT_FALSE(set.ok());
  EXPECT_EQ(set.error().reason, "other_ct");
  EXPECT_NE(set.error().message.find("structure 'ring' was not drawn on this CT (test CT): its "
                                     "frame of reference is 1.2.3.999"),
            std::string::npos)
      << set.error().message;
  // A CT that carries no frame of reference (NRRD) is checked by its slices, and says so.
  CtFrame nrrd = ct_;
  nrrd.frame_of_reference_uid.clear();
  auto read = readStructures(file, nrrd);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_NE(read->notes.back().find("frame of reference not checked"), std::string::npos);
  // Drawn on other slices (the same CT shifted half a slice) is refused too.
  CtFrame shifted = nrrd;
  shifted.geometry.origin_lps_mm.z() += 0.625;
  auto off = readStructures(file, shifted);
  ASSERT_FALSE(off.ok());
  EXPECT_EQ(off.error().reason, "other_ct");
  // Not a structure set at all: pydicom's RT Dose.
  auto dose =
      readStructures("/usr/lib/python3/dist-packages/pydicom/data/test_files/rtdose.dcm", ct_);
  ASSERT_FALSE(dose.ok());
  EXPECT_EQ(dose.error().reason, "unsupported");
  EXPECT_NE(dose.error().message.find("a DICOM RTDOSE object"), std::string::npos);
}

// Every voxel of a structure, on the CT's grid, where the two sets differ.
std::size_t voxelsDiffering(const Structure& a, const Structure& b, const volume::Geometry& ct) {
  std::size_t differ = 0;
  for (int k = 0; k < ct.dims[2]; ++k)
    for (int j = 0; j < ct.dims[1]; ++j)
      for (int i = 0; i < ct.dims[0]; ++i) {
        const Eigen::Vector3d lps = ct.toLps(Eigen::Vector3d(i, j, k));
        differ += a.mask.insideNearest(a.mask.geometry.toIjk(lps)) !=
                  b.mask.insideNearest(b.mask.geometry.toIjk(lps));
      }
  return differ;
}

// Written by ignav, read by ignav and by dicompyler-core: the same voxels, the same volumes.
TEST_F(DicomStructures, AStructureSetWrittenIsReadBackVoxelForVoxel) {
  // An oblique CT (the built-in phantom's is) and shapes with holes, islands and diagonals.
  CtFrame oblique = ct_;
  oblique.geometry.direction =
      Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  std::vector<Shape> shapes{
      {"prostate",
       {0.8, 0.6, 0.2},
       Role::kTarget,
       0.0,
       [](const Eigen::Vector3d& p) { return (p - Eigen::Vector3d(2, -3, 1)).norm() - 15.0; }},
      {"urethra",
       {1.0, 1.0, 0.0},
       Role::kAvoid,
       3.0,
       [](const Eigen::Vector3d& p) {
         // A tube with a tube-shaped hole: every slice has an inner contour.
         const double r = std::hypot(p.x() - 4.0, p.y() + 2.0);
         return std::max({r - 6.0, 2.5 - r, std::abs(p.z()) - 20.0});
       }},
      {"seeds", {0.3, 0.3, 1.0}, Role::kShown, 0.0, [](const Eigen::Vector3d& p) {
         // Islands touching at corners: a checkerboard of 2 mm cubes.
         const auto cell = [](double v) { return static_cast<int>(std::floor(v / 2.0)); };
         const bool on = ((cell(p.x()) + cell(p.y()) + cell(p.z())) & 1) != 0;
         return on && std::abs(p.x() + 20) < 6 && std::abs(p.y() - 18) < 6 && std::abs(p.z()) < 4
                    ? -1.0
                    : 1.0;
       }}};
  auto made = voxelise(oblique.geometry, Eigen::Matrix4d::Identity(), shapes, "shapes");
  ASSERT_TRUE(made.ok()) << made.error().message;
  const std::string file = path("written.dcm");
  RtStructureSetHeader header;
  header.patient_name = "IGNAV^TEST";
  header.patient_id = "T1";
  ASSERT_TRUE(writeRtStructureSet(*made, oblique, header, file).ok());
  auto back = readStructures(file, oblique);
  ASSERT_TRUE(back.ok()) << back.error().message;
  ASSERT_EQ(back->structures.size(), 3u);
  EXPECT_TRUE(back->notes.empty());
  for (std::size_t n = 0; n < 3; ++n) {
    SCOPED_TRACE(made->structures[n].name);
    EXPECT_EQ(back->structures[n].name, made->structures[n].name);
    EXPECT_EQ(back->structures[n].mask.count(), made->structures[n].mask.count());
    EXPECT_EQ(voxelsDiffering(back->structures[n], made->structures[n], oblique.geometry), 0u);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(back->structures[n].colour_rgb[static_cast<std::size_t>(c)],
                  made->structures[n].colour_rgb[static_cast<std::size_t>(c)], 0.5 / 255);
    }
  }
  // dicompyler-core reads what we wrote (on an axial CT: its grid has no oblique axes).
  auto axial = voxelise(ct_.geometry, Eigen::Matrix4d::Identity(), shapes, "shapes");
  ASSERT_TRUE(axial.ok());
  ASSERT_TRUE(writeRtStructureSet(*axial, ct_, header, path("axial.dcm")).ok());
  const auto reference = dicompyler(path("axial.dcm"), ct_.geometry);
  for (const auto& s : axial->structures) {
    SCOPED_TRACE(s.name);
    EXPECT_NEAR(s.mask.volume_cm3(), reference.at(s.name).get<double>(),
                0.01 * s.mask.volume_cm3());
  }
}

// DICOM SEG: written by DCMTK's dcmseg (the library AI segmenters' converters use), read back.
class DicomSegRoundTrip : public DicomStructures {
 protected:
  // Two overlapping segments on every third slice of the CT, frames as dcmseg writes them.
  Status writeSeg(const std::string& file, const std::string& frame_uid,
                  const std::vector<std::vector<std::uint8_t>>& segments,
                  const std::vector<std::string>& labels) {
    const volume::Geometry& g = ct_.geometry;
    IODGeneralEquipmentModule::EquipmentInfo equipment("ignav tests", "ignav", "1", "1");
    ContentIdentificationMacro content("1", "SEG", "ignav test segmentation", "TESTER^A");
    DcmSegmentation* made = nullptr;
    if (DcmSegmentation::createBinarySegmentation(made, static_cast<Uint16>(g.dims[1]),
                                                  static_cast<Uint16>(g.dims[0]), equipment,
                                                  content)
            .bad()) {
      return makeError(ErrorCode::kInternal, "createBinarySegmentation");
    }
    std::unique_ptr<DcmSegmentation> seg(made);
    seg->getFrameOfReference().setFrameOfReferenceUID(frame_uid.c_str());
    seg->getPatient().setPatientName("IGNAV^TEST");
    seg->getSegmentationSeriesModule().setSeriesNumber("1");
    // Frames are indexed by segment, then by their place along the slices (as dcmqi writes them).
    const std::string dimensions_uid = "1.2.826.0.1.3680043.9.7133.41.3";
    seg->getDimensions().addDimensionIndex(DCM_ReferencedSegmentNumber, dimensions_uid.c_str(),
                                           DCM_SegmentIdentificationSequence,
                                           "ReferencedSegmentNumber");
    seg->getDimensions().addDimensionIndex(DCM_ImagePositionPatient, dimensions_uid.c_str(),
                                           DCM_PlanePositionSequence, "ImagePositionPatient");
    FGPlaneOrientationPatient* orientation =
        FGPlaneOrientationPatient::createMinimal("1", "0", "0", "0", "1", "0");
    FGPixelMeasures measures;
    measures.setPixelSpacing(fmt::format("{}\\{}", g.spacing_mm.y(), g.spacing_mm.x()).c_str());
    measures.setSliceThickness(fmt::format("{}", g.spacing_mm.z()).c_str());
    seg->addForAllFrames(*orientation);
    seg->addForAllFrames(measures);
    delete orientation;
    for (std::size_t s = 0; s < segments.size(); ++s) {
      DcmSegment* segment = nullptr;
      CodeSequenceMacro category("T-D0050", "SRT", "Tissue");
      CodeSequenceMacro type("T-D0050", "SRT", "Tissue");
      DcmSegment::create(segment, labels[s].c_str(), category, type, DcmSegTypes::SAT_MANUAL);
      double lab[3];
      IODCIELabUtil::rgb2DicomLab(lab[0], lab[1], lab[2], s == 0 ? 1.0 : 0.0, 0.5, 0.25);
      segment->setRecommendedDisplayCIELabValue(static_cast<Uint16>(std::lround(lab[0])),
                                                static_cast<Uint16>(std::lround(lab[1])),
                                                static_cast<Uint16>(std::lround(lab[2])));
      Uint16 number = 0;
      if (seg->addSegment(segment, number).bad()) return makeError(ErrorCode::kInternal, "segment");
      const std::size_t plane = static_cast<std::size_t>(g.dims[0]) * g.dims[1];
      for (int k = 0; k < g.dims[2]; ++k) {
        const std::uint8_t* in = segments[s].data() + plane * static_cast<std::size_t>(k);
        if (std::none_of(in, in + plane, [](std::uint8_t v) { return v != 0; })) continue;
        std::vector<Uint8> pixels(in, in + plane);
        OFVector<FGBase*> per_frame;
        FGPlanePosPatient* position =
            FGPlanePosPatient::createMinimal("0", "0", "0");  // set below with the slice's place
        const Eigen::Vector3d ipp = g.toLps(Eigen::Vector3d(0, 0, k));
        position->setImagePositionPatient(fmt::format("{}", ipp.x()).c_str(),
                                          fmt::format("{}", ipp.y()).c_str(),
                                          fmt::format("{}", ipp.z()).c_str());
        FGSegmentation segmentation;
        segmentation.setReferencedSegmentNumber(number);
        FGFrameContent frame_content;
        frame_content.setDimensionIndexValues(number, 0);
        frame_content.setDimensionIndexValues(static_cast<Uint32>(k + 1), 1);
        per_frame.push_back(position);
        per_frame.push_back(&segmentation);
        per_frame.push_back(&frame_content);
        const OFCondition c = seg->addFrame(pixels.data(), number, per_frame);
        delete position;
        if (c.bad()) return makeError(ErrorCode::kInternal, std::string("frame: ") + c.text());
      }
    }
    if (OFCondition c = seg->saveFile(file.c_str()); c.bad()) {
      return makeError(ErrorCode::kIo, std::string("saveFile: ") + c.text());
    }
    return Ok{};
  }
  std::vector<std::uint8_t> sphere(const Eigen::Vector3d& centre, double radius) const {
    const volume::Geometry& g = ct_.geometry;
    std::vector<std::uint8_t> in(g.voxelCount(), 0);
    std::size_t n = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i, ++n)
          in[n] = (g.toLps(Eigen::Vector3d(i, j, k)) - centre).norm() <= radius;
    return in;
  }
};

TEST_F(DicomSegRoundTrip, ASegmentationMadeByDcmsegIsReadBackVoxelForVoxel) {
  const auto a = sphere({3.1, -2.2, 4.4}, 9.0), b = sphere({9.0, 1.0, 2.0}, 6.5);
  const std::string file = path("seg.dcm");
  ASSERT_TRUE(writeSeg(file, ct_.frame_of_reference_uid, {a, b}, {"prostate", "urethra"}).ok());
  auto set = readStructures(file, ct_);
  ASSERT_TRUE(set.ok()) << set.error().message;
  ASSERT_EQ(set->structures.size(), 2u);
  const volume::Geometry& g = ct_.geometry;
  for (std::size_t s = 0; s < 2; ++s) {
    const Structure& st = set->structures[s];
    EXPECT_EQ(st.name, s == 0 ? "prostate" : "urethra");
    const auto& truth = s == 0 ? a : b;
    std::size_t n = 0, differ = 0;
    for (int k = 0; k < g.dims[2]; ++k)
      for (int j = 0; j < g.dims[1]; ++j)
        for (int i = 0; i < g.dims[0]; ++i, ++n)
          differ +=
              st.mask.insideNearest(st.mask.geometry.toIjk(g.toLps(Eigen::Vector3d(i, j, k)))) !=
              (truth[n] != 0);
    EXPECT_EQ(differ, 0u);
    EXPECT_EQ(st.mask.count(),
              static_cast<std::size_t>(std::count(truth.begin(), truth.end(), std::uint8_t{1})));
  }
  // The colours survive DICOM's CIELab within rounding.
  EXPECT_NEAR(set->structures[0].colour_rgb[0], 1.0, 0.01);
  EXPECT_NEAR(set->structures[0].colour_rgb[1], 0.5, 0.01);
  EXPECT_NEAR(set->structures[1].colour_rgb[2], 0.25, 0.01);

  // Another frame of reference, another slice grid: refused, naming how.
  ASSERT_TRUE(writeSeg(path("other.dcm"), "1.2.3.999", {a}, {"prostate"}).ok());
  auto other = readStructures(path("other.dcm"), ct_);
  ASSERT_FALSE(other.ok());
  EXPECT_EQ(other.error().reason, "other_ct");
  EXPECT_NE(other.error().message.find("its frame of reference is 1.2.3.999"), std::string::npos);
  CtFrame shifted = ct_;
  shifted.geometry.origin_lps_mm.x() += 0.4;
  auto off = readStructures(file, shifted);
  ASSERT_FALSE(off.ok());
  EXPECT_EQ(off.error().reason, "other_ct");
  EXPECT_NE(off.error().message.find("is not one of the CT's slices"), std::string::npos);
}

}  // namespace
}  // namespace ignav::anatomy
