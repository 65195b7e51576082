// The DICOM reader against real third-party files (Debian's python3-pydicom test data) and the
// phantom series. Reference values were read with pydicom (dcmread(...).pixel_array and the
// geometry tags), an implementation independent of DCMTK.
#include <dcmtk/config/osconfig.h>  // must come first
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "ignav/volume/dicom.hpp"
#include "ignav/volume/phantom.hpp"
#include "scratch.hpp"

namespace ignav::volume {
namespace {

namespace fs = std::filesystem;
const std::string kPydicom = "/usr/lib/python3/dist-packages/pydicom/data/test_files/";

std::string data(const std::string& name) {
  const std::string p = kPydicom + name;
  if (!fs::exists(p)) ADD_FAILURE() << p << " missing: tools/setup.sh installs python3-pydicom";
  return p;
}

TEST(Dicom, CtSmallGeometryAndHounsfieldValues) {
  const auto r = readDicomSeries({data("CT_small.dcm")});
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Volume& v = r->volume;
  EXPECT_EQ(v.modality, "CT");
  EXPECT_EQ(v.geometry.dims, (std::array<int, 3>{128, 128, 1}));
  EXPECT_NEAR(v.geometry.spacing_mm.x(), 0.661468, 1e-9);
  EXPECT_NEAR(v.geometry.origin_lps_mm.x(), -158.135803, 1e-9);
  EXPECT_NEAR(v.geometry.origin_lps_mm.y(), -179.035797, 1e-9);
  EXPECT_NEAR(v.geometry.origin_lps_mm.z(), -75.699997, 1e-9);
  // pydicom: pixel_array[row 10, col 20] = 185, [0,0] = 175, [64,64] = 1928; intercept -1024.
  EXPECT_EQ(v.valueAt(20, 10, 0), 185 - 1024);
  EXPECT_EQ(v.valueAt(0, 0, 0), 175 - 1024);
  EXPECT_EQ(v.valueAt(64, 64, 0), 1928 - 1024);
  const auto [lo, hi] = v.valueRange();
  EXPECT_EQ(lo, 128 - 1024);
  EXPECT_EQ(hi, 2191 - 1024);
  // Pixel (i, j) lies at origin + i * row direction * column spacing + j * column direction * row
  // spacing.
  const Eigen::Vector3d p = v.geometry.toLps(Eigen::Vector3d(20, 10, 0));
  EXPECT_NEAR(p.x(), -158.135803 + 20 * 0.661468, 1e-9);
  EXPECT_NEAR(p.y(), -179.035797 + 10 * 0.661468, 1e-9);
}

TEST(Dicom, EveryTransferSyntaxDecodesToTheSamePixels) {
  // MR_small in several encodings (explicit/implicit/big endian, RLE, JPEG-LS lossless).
  const auto ref = readDicomSeries({data("MR_small.dcm")});
  ASSERT_TRUE(ref.ok()) << ref.error().message;
  EXPECT_EQ(ref->volume.valueAt(20, 10, 0), 316);  // pydicom
  EXPECT_EQ(ref->volume.valueAt(40, 32, 0), 1281);
  EXPECT_EQ(ref->volume.valueAt(63, 63, 0), 862);
  for (const char* name : {"MR_small_implicit.dcm", "MR_small_bigendian.dcm", "MR_small_RLE.dcm",
                           "MR_small_jpeg_ls_lossless.dcm", "MR_small_padded.dcm"}) {
    const auto r = readDicomSeries({data(name)});
    ASSERT_TRUE(r.ok()) << name << ": " << r.error().message;
    EXPECT_EQ(r->volume.voxels, ref->volume.voxels) << name;
    EXPECT_TRUE(r->volume.geometry.origin_lps_mm.isApprox(ref->volume.geometry.origin_lps_mm))
        << name;
  }
}

TEST(Dicom, Jpeg2000IsRefusedWithAReason) {
  const auto r = readDicomSeries({data("MR_small_jp2klossless.dcm")});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(r.error().message.find("JPEG 2000"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("MR_small_jp2klossless.dcm"), std::string::npos);
}

TEST(Dicom, SlicesAreOrderedByPositionNotInstanceNumber) {
  // CT5N: InstanceNumber 6..10 runs from z = 8.7625 down to -1.2375; the volume's k runs up the
  // slice normal (+z), so k = 0 is instance 10 (file 3353) and k = 4 instance 6 (file 2062).
  const auto r = readDicomSeries({data("dicomdirtests/98892001/CT5N")});
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Volume& v = r->volume;
  EXPECT_EQ(v.geometry.dims, (std::array<int, 3>{16, 16, 5}));
  EXPECT_NEAR(v.geometry.origin_lps_mm.z(), -1.2375, 1e-9);
  EXPECT_NEAR(v.geometry.spacing_mm.z(), 2.5, 2e-3);
  EXPECT_EQ(v.valueAt(4, 3, 0), 925 - 1024);  // pydicom pixel_array[3, 4] of file 3353
  EXPECT_EQ(v.valueAt(2, 10, 0), 905 - 1024);
  EXPECT_EQ(v.valueAt(4, 3, 4), 1018 - 1024);  // file 2062
  EXPECT_EQ(v.valueAt(4, 3, 2), 1042 - 1024);  // file 2693
}

TEST(Dicom, FolderWithManySeriesListsThemAndPicksTheLargestCt) {
  const auto r = readDicomSeries({data("dicomdirtests/98892001")});
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_EQ(r->series.size(), 2u);
  EXPECT_EQ(r->series.front().frames, 5u);
  EXPECT_EQ(r->volume.geometry.dims[2], 5);
  // Choosing the other one by UID works; an unknown UID lists what is there.
  const auto other =
      readDicomSeries({data("dicomdirtests/98892001")}, {r->series.back().uid, false, {}});
  ASSERT_FALSE(other.ok());  // CT2N: 2 slices 265 mm apart with SliceThickness 650: not a grid
  const auto unknown = readDicomSeries({data("dicomdirtests/98892001")}, {"1.2.3", false, {}});
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.error().message.find(r->series.front().uid), std::string::npos);
}

TEST(Dicom, NonImageFilesAreSkippedWithANote) {
  const fs::path dir = testing::scratchDir();
  for (const char* name : {"CT_small.dcm", "test-SR.dcm", "rtplan.dcm"}) {
    fs::copy_file(data(name), dir / name);
  }
  fs::copy_file(data("dicomdirtests/DICOMDIR"), dir / "DICOMDIR");
  std::ofstream(dir / "notes.txt") << "not a DICOM file\n";
  const auto r = readDicomSeries({dir.string()});
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->series.size(), 1u);
  EXPECT_EQ(r->notes.size(), 4u);
  std::string all;
  for (const auto& n : r->notes)
    all += n + "\n";
  EXPECT_NE(all.find("DICOMDIR"), std::string::npos) << all;
  EXPECT_NE(all.find("notes.txt: skipped"), std::string::npos) << all;
}

TEST(Dicom, IrregularSeriesAreReportedNotGuessed) {
  // Radial slices (MR700) have differing orientations.
  auto r = readDicomSeries({data("dicomdirtests/98892003/MR700")});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("ImageOrientationPatient"), std::string::npos)
      << r.error().message;
  // CT2 (77654033): one slice 202.5 mm from three others 1.25 mm apart.
  r = readDicomSeries({data("dicomdirtests/77654033/CT2")});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("missing slice"), std::string::npos) << r.error().message;
}

TEST(Dicom, MalformedFilesGetAnErrorNamingTheFile) {
  auto r = readDicomSeries({data("MR_truncated.dcm")});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("MR_truncated.dcm"), std::string::npos) << r.error().message;
  r = readDicomSeries({"/nonexistent/series"});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kIo);
  // 32-bit RT dose is read but refused with its reason.
  r = readDicomSeries({data("rtdose.dcm")});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("BitsAllocated 32"), std::string::npos) << r.error().message;
  // Garbage and a truncated copy of a good file.
  const fs::path dir = testing::scratchDir();
  std::ofstream(dir / "junk.dcm") << std::string(300, 'x');
  std::ifstream in(data("CT_small.dcm"), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), {});
  std::ofstream(dir / "cut.dcm", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  r = readDicomSeries({dir.string()});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("cut.dcm"), std::string::npos) << r.error().message;
}

TEST(Phantom, SeriesReadsBackExactlyWhateverTheFileOrder) {
  PhantomSpec spec;
  spec.dims = {40, 36, 24};
  spec.noise_sigma_hu = 5.0;
  const Volume made = makePhantom(spec).value();
  const fs::path dir = testing::scratchDir();
  DicomWriteOptions options;
  options.reverse_instance_numbers = true;
  const auto files = writeDicomSeries(made, dir.string(), options).value();
  ASSERT_EQ(files.size(), 24u);
  // Rename the files in shuffled order so neither names nor InstanceNumbers give the order.
  std::vector<std::string> names;
  for (std::size_t i = 0; i < files.size(); ++i)
    names.push_back("f" + std::to_string(i));
  std::shuffle(names.begin(), names.end(), std::mt19937(3));
  for (std::size_t i = 0; i < files.size(); ++i)
    fs::rename(files[i], dir / names[i]);
  std::vector<Progress> seen;
  DicomLoadOptions load;
  load.progress = [&](const Progress& p) { seen.push_back(p); };
  const auto r = readDicomSeries({dir.string()}, load);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->volume.voxels, made.voxels);
  EXPECT_EQ(r->volume.geometry.dims, made.geometry.dims);
  EXPECT_TRUE(r->volume.geometry.ijkToLps().isApprox(made.geometry.ijkToLps(), 1e-9));
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back().stage, "decode");
  EXPECT_EQ(seen.back().done, 24u);
}

TEST(Phantom, ParallelDecodingIsDeterministic) {
  PhantomSpec spec;
  spec.dims = {64, 48, 40};  // 6 KB of pixels per file: DCMTK leaves them on disk until decoding
  spec.noise_sigma_hu = 5.0;
  const Volume made = makePhantom(spec).value();
  const fs::path dir = testing::scratchDir();
  const auto files = writeDicomSeries(made, dir.string()).value();
  for (int threads : {1, 2, 5}) {
    DicomLoadOptions options;
    options.threads = threads;
    const auto r = readDicomSeries({dir.string()}, options);
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_EQ(r->volume.voxels, made.voxels) << threads << " threads";
  }
  // Two files whose last pixel (the file's last two bytes) is 65535 - 1024 HU, beyond int16:
  // whatever the timing, the first of them in file order is reported.
  for (std::size_t victim : {std::size_t{7}, std::size_t{30}}) {
    std::fstream f(files[victim], std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(-2, std::ios::end);
    f.put('\xff').put('\xff');
  }
  for (int run = 0; run < 5; ++run) {
    DicomLoadOptions options;
    options.threads = 4;
    const auto r = readDicomSeries({dir.string()}, options);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("slice_0007.dcm"), std::string::npos) << r.error().message;
  }
}

TEST(Phantom, AHeaderThatOverstatesItsPixelsIsRefusedBeforeAllocating) {
  // dcmodify (DCMTK's command-line tool) sets NumberOfFrames to 10^6 in a 3 KB slice: 3 GB
  // declared. The reader must say so, not allocate it.
  PhantomSpec spec;
  spec.dims = {32, 32, 1};
  const fs::path dir = testing::scratchDir();
  const auto files = writeDicomSeries(makePhantom(spec).value(), dir.string()).value();
  const std::string cmd = "dcmodify -nb -i \"(0028,0008)=1000000\" " + files[0] + " 2>/dev/null";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "dcmodify (package dcmtk) is needed";
  const auto r = readDicomSeries({dir.string()});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("declares 32 x 32 x 1000000 pixels"), std::string::npos)
      << r.error().message;
}

TEST(Phantom, ObliqueSeriesKeepsItsDirection) {
  PhantomSpec spec;
  spec.dims = {32, 32, 16};
  spec.oblique = true;
  const Volume made = makePhantom(spec).value();
  EXPECT_GT(std::abs(made.geometry.direction(2, 0)), 0.05);  // really tilted
  const fs::path dir = testing::scratchDir();
  ASSERT_TRUE(writeDicomSeries(made, dir.string()).ok());
  const auto r = readDicomSeries({dir.string()});
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_TRUE(r->volume.geometry.direction.isApprox(made.geometry.direction, 1e-6));
  EXPECT_TRUE(r->volume.geometry.origin_lps_mm.isApprox(made.geometry.origin_lps_mm, 1e-6));
  EXPECT_EQ(r->volume.voxels, made.voxels);
}

TEST(Phantom, FiducialsAreBrightWhereTheyWereAsked) {
  PhantomSpec spec;
  const Volume v = makePhantom(spec).value();
  for (const auto& f : spec.fiducials_lps_mm)
    EXPECT_GT(v.sampleLps(f, -2000), 2000.0);
  EXPECT_NEAR(v.sampleLps({0, 0, 0}, -2000), spec.box_hu, 1e-9);   // gelatin
  EXPECT_NEAR(v.sampleLps({36, 0, 0}, -2000), spec.air_hu, 1e-9);  // air outside the box
}

// Compressed series are decoded frame by frame into the reader's own buffer (issue 28). DCMTK's
// command-line encoders (package dcmtk, run as separate processes) compress a phantom series
// losslessly; every encoding must read back to exactly the phantom's voxels, on one thread and on
// two.
std::vector<std::string> compressEach(const std::vector<std::string>& files, const fs::path& to,
                                      const std::string& encoder) {
  fs::create_directories(to);
  std::vector<std::string> out;
  for (const auto& f : files) {
    const std::string dst = (to / fs::path(f).filename()).string();
    const std::string cmd = encoder + " \"" + f + "\" \"" + dst + "\"";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd << ": DCMTK's encoders (package dcmtk)";
    out.push_back(dst);
  }
  return out;
}

TEST(Phantom, LosslessCompressedSeriesReadBackExactly) {
  PhantomSpec spec;
  spec.dims = {48, 40, 12};
  spec.noise_sigma_hu = 20.0;  // so that every codec has real entropy to code
  const Volume made = makePhantom(spec).value();
  const fs::path dir = testing::scratchDir();
  const auto files = writeDicomSeries(made, (dir / "native").string()).value();
  // JPEG lossless (process 14, first-order and predictor 6), JPEG-LS, RLE; one with an empty
  // basic offset table and 1 KB fragments, so that the frame's fragments must be found by walking.
  const std::vector<std::pair<std::string, std::string>> encoders = {
      {"jpeg_sv1", "dcmcjpeg +e1"},
      {"jpeg_sv6", "dcmcjpeg +el +sv 6"},
      {"jpeg_ls", "dcmcjpls"},
      {"rle", "dcmcrle"},
      {"jpeg_ls_fragments", "dcmcjpls -ot +fs 1"}};
  for (const auto& [name, encoder] : encoders) {
    compressEach(files, dir / name, encoder);
    for (int threads : {1, 2}) {
      DicomLoadOptions options;
      options.threads = threads;
      const auto r = readDicomSeries({(dir / name).string()}, options);
      ASSERT_TRUE(r.ok()) << name << ": " << r.error().message;
      EXPECT_EQ(r->volume.voxels, made.voxels) << name << ", " << threads << " threads";
      EXPECT_TRUE(r->volume.geometry.ijkToLps().isApprox(made.geometry.ijkToLps(), 1e-9)) << name;
    }
  }
  // A compressed frame that cannot be decoded (its code stream overwritten, the file's length
  // kept) is refused with an error that names the file and the frame.
  const fs::path victim = dir / "jpeg_ls" / fs::path(files[5]).filename();
  {
    std::fstream f(victim, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(-400, std::ios::end);
    for (int i = 0; i < 300; ++i)
      f.put('\xff');
  }
  const auto broken = readDicomSeries({(dir / "jpeg_ls").string()});
  ASSERT_FALSE(broken.ok());
  EXPECT_EQ(broken.error().code, ErrorCode::kFormat) << broken.error().message;
  EXPECT_NE(broken.error().message.find(victim.filename().string()), std::string::npos)
      << broken.error().message;
  EXPECT_NE(broken.error().message.find("frame 1"), std::string::npos) << broken.error().message;
}

// One legacy multi-frame file (as RT dose and some CT exports): the slices' pixels as frames,
// placed by GridFrameOffsetVector; made with DCMTK's API from the single-frame files.
std::string joinFrames(const std::vector<std::string>& slices, double spacing_mm,
                       const fs::path& out) {
  DcmFileFormat joined;
  EXPECT_TRUE(joined.loadFile(slices.front().c_str()).good());
  DcmDataset* ds = joined.getDataset();
  std::vector<Uint16> pixels;
  std::ostringstream offsets;
  for (std::size_t f = 0; f < slices.size(); ++f) {
    DcmFileFormat one;
    EXPECT_TRUE(one.loadFile(slices[f].c_str()).good());
    const Uint16* p = nullptr;
    unsigned long n = 0;
    EXPECT_TRUE(one.getDataset()->findAndGetUint16Array(DCM_PixelData, p, &n).good());
    pixels.insert(pixels.end(), p, p + n);
    offsets << (f ? "\\" : "") << static_cast<double>(f) * spacing_mm;
  }
  ds->putAndInsertUint16Array(DCM_PixelData, pixels.data(), pixels.size());
  ds->putAndInsertString(DCM_NumberOfFrames, std::to_string(slices.size()).c_str());
  ds->putAndInsertString(DCM_GridFrameOffsetVector, offsets.str().c_str());
  fs::create_directories(out.parent_path());
  EXPECT_TRUE(joined.saveFile(out.c_str(), EXS_LittleEndianExplicit).good());
  return out.string();
}

TEST(Phantom, CompressedMultiFrameFileReadsBackExactly) {
  PhantomSpec spec;
  spec.dims = {40, 32, 9};
  spec.noise_sigma_hu = 20.0;
  const Volume made = makePhantom(spec).value();
  const fs::path dir = testing::scratchDir();
  const auto files = writeDicomSeries(made, (dir / "native").string()).value();
  const std::string multi =
      joinFrames(files, made.geometry.spacing_mm.z(), dir / "multi" / "volume.dcm");
  const auto native = readDicomSeries({multi});
  ASSERT_TRUE(native.ok()) << native.error().message;
  ASSERT_EQ(native->volume.voxels, made.voxels);
  // Fragments found by walking (no offset table, several per frame) and from the table.
  for (const std::string encoder : {"dcmcjpls -ot +fs 1", "dcmcjpeg +e1", "dcmcrle -ot"}) {
    const auto packed =
        compressEach({multi}, dir / ("packed" + std::to_string(encoder.size())), encoder);
    const auto r = readDicomSeries({packed.front()});
    ASSERT_TRUE(r.ok()) << encoder << ": " << r.error().message;
    EXPECT_EQ(r->volume.voxels, made.voxels) << encoder;
  }
}

TEST(Phantom, MissingAndDuplicateSlicesAreDetected) {
  PhantomSpec spec;
  spec.dims = {16, 16, 10};
  const Volume made = makePhantom(spec).value();
  const fs::path dir = testing::scratchDir();
  const auto files = writeDicomSeries(made, dir.string()).value();
  fs::remove(files[4]);
  auto r = readDicomSeries({dir.string()});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("1 missing slice(s)"), std::string::npos) << r.error().message;
  DicomLoadOptions fill;
  fill.fill_missing_slices = true;
  r = readDicomSeries({dir.string()}, fill);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->volume.geometry.dims[2], 10);
  EXPECT_EQ(r->warnings.size(), 1u);
  // A duplicate: the same slice twice under another name.
  fs::copy_file(files[2], dir / "copy_of_slice_2.dcm");
  r = readDicomSeries({dir.string()}, fill);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("duplicate slice position"), std::string::npos)
      << r.error().message;
}

}  // namespace
}  // namespace ignav::volume
