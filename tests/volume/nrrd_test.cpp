// NRRD files written by hand exactly as 3D Slicer writes them, with voxel values and LPS
// positions computed by hand from the header.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "ignav/volume/image_io.hpp"
#include "scratch.hpp"

namespace ignav::volume {
namespace {

using namespace testing;  // scratchDir, writeFile, Bytes, fs

Bytes int16Le(const std::vector<int>& values) {
  Bytes b;
  for (int v : values) {
    const auto u = static_cast<std::uint16_t>(static_cast<std::int16_t>(v));
    b.push_back(static_cast<std::uint8_t>(u & 0xff));
    b.push_back(static_cast<std::uint8_t>(u >> 8));
  }
  return b;
}

Bytes gzip(const Bytes& raw) {
  z_stream zs{};
  deflateInit2(&zs, 9, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY);  // gzip wrapper
  Bytes out(deflateBound(&zs, static_cast<uLong>(raw.size())) + 64);
  zs.next_in = const_cast<Bytef*>(raw.data());
  zs.avail_in = static_cast<uInt>(raw.size());
  zs.next_out = out.data();
  zs.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(deflate(&zs, Z_FINISH), Z_STREAM_END);
  out.resize(zs.total_out);
  deflateEnd(&zs);
  return out;
}

// 3 x 4 x 5 voxels, value i + 10 j + 100 k - 250: every voxel distinct, some negative.
int refValue(int i, int j, int k) {
  return i + 10 * j + 100 * k - 250;
}
std::vector<int> refValues() {
  std::vector<int> v;
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 3; ++i)
        v.push_back(refValue(i, j, k));
  return v;
}

// Header as Slicer 5 writes it (vtkNRRDWriter / teem).
std::string slicerHeader(const std::string& type, const std::string& encoding,
                         const std::string& space = "left-posterior-superior",
                         const std::string& directions = "(0.5,0,0) (0,0.75,0) (0,0,2.5)",
                         const std::string& origin = "(-10,20,30)",
                         const std::string& endian = "little") {
  return "NRRD0004\n"
         "# Complete NRRD file format specification at:\n"
         "# http://teem.sourceforge.net/nrrd/format.html\n"
         "type: " +
         type +
         "\n"
         "dimension: 3\n"
         "space: " +
         space +
         "\n"
         "sizes: 3 4 5\n"
         "space directions: " +
         directions +
         "\n"
         "kinds: domain domain domain\n"
         "endian: " +
         endian +
         "\n"
         "encoding: " +
         encoding +
         "\n"
         "space origin: " +
         origin +
         "\n"
         "\n";
}

void expectRefVolume(const Volume& v) {
  ASSERT_EQ(v.geometry.dims, (std::array<int, 3>{3, 4, 5}));
  ASSERT_EQ(v.voxels.size(), 60u);
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 3; ++i)
        ASSERT_DOUBLE_EQ(v.valueAt(i, j, k), refValue(i, j, k));
}

TEST(Nrrd, SlicerAttachedRawShortGivesValuesAndLpsGeometry) {
  const auto path =
      writeFile(scratchDir() / "ct.nrrd", slicerHeader("short", "raw"), int16Le(refValues()));
  const auto v = readNrrd(path);
  ASSERT_TRUE(v.ok()) << v.error().message;
  expectRefVolume(*v);
  // Voxel (1, 2, 3): origin + (1 * 0.5, 2 * 0.75, 3 * 2.5), by hand.
  const Eigen::Vector3d p = v->geometry.toLps({1, 2, 3});
  EXPECT_NEAR(p.x(), -9.5, 1e-12);
  EXPECT_NEAR(p.y(), 21.5, 1e-12);
  EXPECT_NEAR(p.z(), 37.5, 1e-12);
  EXPECT_DOUBLE_EQ(v->geometry.spacing_mm.z(), 2.5);
  EXPECT_EQ(v->description, "ct.nrrd");
}

TEST(Nrrd, RasSpaceIsFlippedToLps) {
  // Slicer in RAS: i runs toward -R (=L), origin R 10 A 20 S 30.
  const auto path = writeFile(scratchDir() / "ras.nrrd",
                              slicerHeader("short", "raw", "right-anterior-superior",
                                           "(-0.5,0,0) (0,-0.75,0) (0,0,2.5)", "(10,20,30)"),
                              int16Le(refValues()));
  const auto v = readNrrd(path);
  ASSERT_TRUE(v.ok()) << v.error().message;
  // RAS (10 - 0.5 i, 20 - 0.75 j, 30 + 2.5 k) is LPS (-10 + 0.5 i, -20 + 0.75 j, 30 + 2.5 k).
  const Eigen::Vector3d p = v->geometry.toLps({2, 1, 4});
  EXPECT_NEAR(p.x(), -9.0, 1e-12);
  EXPECT_NEAR(p.y(), -19.25, 1e-12);
  EXPECT_NEAR(p.z(), 40.0, 1e-12);
  EXPECT_NEAR(v->geometry.direction(0, 0), 1.0, 1e-12);
}

TEST(Nrrd, ObliqueDirectionsAreNormalisedColumns) {
  // Axis i along (0.6, 0.8, 0) with 2 mm spacing, j along (-0.8, 0.6, 0) with 1 mm.
  const auto path = writeFile(scratchDir() / "obl.nrrd",
                              slicerHeader("short", "raw", "left-posterior-superior",
                                           "(1.2,1.6,0) (-0.8,0.6,0) (0,0,3)", "(0,0,0)"),
                              int16Le(refValues()));
  const auto v = readNrrd(path);
  ASSERT_TRUE(v.ok()) << v.error().message;
  EXPECT_NEAR(v->geometry.spacing_mm.x(), 2.0, 1e-12);
  const Eigen::Vector3d p = v->geometry.toLps({1, 1, 1});  // (1.2 - 0.8, 1.6 + 0.6, 3)
  EXPECT_NEAR(p.x(), 0.4, 1e-12);
  EXPECT_NEAR(p.y(), 2.2, 1e-12);
  EXPECT_NEAR(p.z(), 3.0, 1e-12);
}

TEST(Nrrd, GzipEncodingFromZlib) {
  const auto path = writeFile(scratchDir() / "gz.nrrd", slicerHeader("short", "gzip"),
                              gzip(int16Le(refValues())));
  const auto v = readNrrd(path);
  ASSERT_TRUE(v.ok()) << v.error().message;
  expectRefVolume(*v);
}

// Found by fuzz_nrrd: float values whose grid level lies past int16 were converted anyway
// (undefined behaviour). Such a file is refused with the reason.
TEST(Nrrd, FloatLevelsPastInt16AreRefusedNotConverted) {
  const auto v =
      readNrrd(IGNAV_SOURCE_DIR "/tests/fuzz/regressions/nrrd/float_levels_past_int16.nrrd");
  ASSERT_FALSE(v.ok());
  EXPECT_NE(v.error().message.find("not on a grid"), std::string::npos) << v.error().message;
}

TEST(Nrrd, BigEndianShort) {
  Bytes be;
  for (int x : refValues()) {
    const auto u = static_cast<std::uint16_t>(static_cast<std::int16_t>(x));
    be.push_back(static_cast<std::uint8_t>(u >> 8));
    be.push_back(static_cast<std::uint8_t>(u & 0xff));
  }
  const auto path = writeFile(scratchDir() / "be.nrrd",
                              slicerHeader("short", "raw", "left-posterior-superior",
                                           "(0.5,0,0) (0,0.75,0) (0,0,2.5)", "(-10,20,30)", "big"),
                              be);
  const auto v = readNrrd(path);
  ASSERT_TRUE(v.ok()) << v.error().message;
  expectRefVolume(*v);
}

TEST(Nrrd, BigEndianFloatWithIntegralValuesIsExact) {
  Bytes be;
  for (int x : refValues()) {
    const float f = static_cast<float>(x);
    std::uint32_t u = 0;
    std::memcpy(&u, &f, 4);
    for (int s = 24; s >= 0; s -= 8)
      be.push_back(static_cast<std::uint8_t>((u >> s) & 0xff));
  }
  const auto path = writeFile(scratchDir() / "bef.nrrd",
                              slicerHeader("float", "raw", "left-posterior-superior",
                                           "(0.5,0,0) (0,0.75,0) (0,0,2.5)", "(-10,20,30)", "big"),
                              be);
  const auto v = readNrrd(path);
  ASSERT_TRUE(v.ok()) << v.error().message;
  expectRefVolume(*v);
}

TEST(Nrrd, Uint16AboveInt16RangeIsShiftedExactly) {
  std::vector<std::uint16_t> values(60);
  for (std::size_t n = 0; n < values.size(); ++n)
    values[n] = static_cast<std::uint16_t>(n * 1111);
  values[7] = 65535;
  Bytes raw(values.size() * 2);
  std::memcpy(raw.data(), values.data(), raw.size());  // host is little-endian here
  const auto path = writeFile(scratchDir() / "u16.nrrd", slicerHeader("ushort", "raw"), raw);
  const auto v = readNrrd(path);
  ASSERT_TRUE(v.ok()) << v.error().message;
  for (std::size_t n = 0; n < values.size(); ++n) {
    ASSERT_DOUBLE_EQ(v->voxels[n] * v->value_scale + v->value_offset, values[n]) << n;
  }
}

TEST(Nrrd, Uint8AndInt32InRangeAreExact) {
  Bytes u8(60);
  for (std::size_t n = 0; n < 60; ++n)
    u8[n] = static_cast<std::uint8_t>(200 + n % 50);
  auto v = readNrrd(writeFile(scratchDir() / "u8.nrrd", slicerHeader("uchar", "raw"), u8));
  ASSERT_TRUE(v.ok()) << v.error().message;
  EXPECT_DOUBLE_EQ(v->valueAt(2, 3, 4), 200 + 59 % 50);

  std::vector<std::int32_t> i32(60);
  for (std::size_t n = 0; n < 60; ++n)
    i32[n] = 100000 + static_cast<std::int32_t>(n);
  Bytes raw(240);
  std::memcpy(raw.data(), i32.data(), raw.size());
  v = readNrrd(writeFile(scratchDir() / "i32.nrrd", slicerHeader("int", "raw"), raw));
  ASSERT_TRUE(v.ok()) << v.error().message;
  EXPECT_DOUBLE_EQ(v->valueAt(2, 3, 4), 100059);
  EXPECT_DOUBLE_EQ(v->valueAt(0, 0, 0), 100000);
}

TEST(Nrrd, NonGridFloatAndWideIntAreUnsupportedNamingTheType) {
  std::vector<float> f(60);
  for (std::size_t n = 0; n < 60; ++n)
    f[n] = std::sqrt(static_cast<float>(n) + 0.5f);
  Bytes raw(240);
  std::memcpy(raw.data(), f.data(), raw.size());
  const auto path = writeFile(scratchDir() / "f.nrrd", slicerHeader("float", "raw"), raw);
  auto v = readNrrd(path);
  ASSERT_FALSE(v.ok());
  EXPECT_EQ(v.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(v.error().message.find("float"), std::string::npos) << v.error().message;
  EXPECT_NE(v.error().message.find(path), std::string::npos);

  std::vector<std::int32_t> i32(60, 0);
  i32[3] = 1000000;
  std::memcpy(raw.data(), i32.data(), raw.size());
  v = readNrrd(writeFile(scratchDir() / "wide.nrrd", slicerHeader("int", "raw"), raw));
  ASSERT_FALSE(v.ok());
  EXPECT_EQ(v.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(v.error().message.find("int32"), std::string::npos) << v.error().message;
}

TEST(Nrrd, DetachedHeaderWithDataFile) {
  const auto dir = scratchDir();
  writeFile(dir / "ct.raw", "", int16Le(refValues()));
  std::string header = slicerHeader("short", "raw");
  header.pop_back();  // a .nhdr has no blank line
  header += "data file: ct.raw\n";
  const auto v = readNrrd(writeFile(dir / "ct.nhdr", header));
  ASSERT_TRUE(v.ok()) << v.error().message;
  expectRefVolume(*v);
}

TEST(Nrrd, ProgressReportsCompletion) {
  const auto path =
      writeFile(scratchDir() / "p.nrrd", slicerHeader("short", "gzip"), gzip(int16Le(refValues())));
  std::size_t last_done = 0, last_total = 0, calls = 0;
  const auto v = readNrrd(path, [&](const Progress& p) {
    ++calls;
    last_done = p.done;
    last_total = p.total;
  });
  ASSERT_TRUE(v.ok()) << v.error().message;
  EXPECT_GE(calls, 1u);
  EXPECT_EQ(last_done, 120u);
  EXPECT_EQ(last_total, 120u);
}

Volume obliqueVolume() {
  Volume v;
  v.geometry.dims = {7, 6, 5};
  v.geometry.spacing_mm = {0.7, 0.9, 2.5};
  v.geometry.origin_lps_mm = {-120.25, 33.5, -401.0};
  const double c = std::cos(0.3), s = std::sin(0.3);
  v.geometry.direction << c, -s, 0, s, c, 0, 0, 0, -1;  // rotated, k toward inferior
  v.voxels.resize(v.geometry.voxelCount());
  for (std::size_t n = 0; n < v.voxels.size(); ++n) {
    v.voxels[n] = static_cast<std::int16_t>(static_cast<int>(n * 37 % 4000) - 1024);
  }
  return v;
}

TEST(Nrrd, WriteReadRoundTripInt16RawAndGzip) {
  const Volume in = obliqueVolume();
  for (auto enc : {NrrdEncoding::kRaw, NrrdEncoding::kGzip}) {
    const auto path = (scratchDir() / "rt.nrrd").string();
    ASSERT_TRUE(writeNrrd(in, path, enc).ok());
    std::ifstream f(path);
    std::string text((std::istreambuf_iterator<char>(f)), {});
    EXPECT_NE(text.find("type: short\n"), std::string::npos);
    EXPECT_NE(text.find("space: left-posterior-superior\n"), std::string::npos);
    EXPECT_NE(text.find(enc == NrrdEncoding::kGzip ? "encoding: gzip\n" : "encoding: raw\n"),
              std::string::npos);
    const auto out = readNrrd(path);
    ASSERT_TRUE(out.ok()) << out.error().message;
    EXPECT_EQ(out->voxels, in.voxels);
    EXPECT_EQ(out->value_scale, 1.0);
    EXPECT_EQ(out->value_offset, 0.0);
    EXPECT_EQ(out->geometry.dims, in.geometry.dims);
    EXPECT_LT((out->geometry.ijkToLps() - in.geometry.ijkToLps()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(Nrrd, WriteReadRoundTripRescaledValuesAsDouble) {
  Volume in = obliqueVolume();
  in.value_scale = 0.1;
  in.value_offset = -1024.3;
  const auto path = (scratchDir() / "scaled.nrrd").string();
  ASSERT_TRUE(writeNrrd(in, path).ok());
  const auto out = readNrrd(path);
  ASSERT_TRUE(out.ok()) << out.error().message;
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 6; ++j)
      for (int i = 0; i < 7; ++i)
        ASSERT_NEAR(out->valueAt(i, j, k), in.valueAt(i, j, k), 1e-9);
}

// A scan's voxels as they came (uint16 above int16's range; float32 on a 0.5 grid) are read back
// exactly, on the same oblique geometry; a short buffer or a skewed geometry is refused by name.
TEST(Nrrd, VoxelsWrittenAsTheyCameReadBackExactly) {
  const Geometry g = obliqueVolume().geometry;
  const std::size_t n = g.voxelCount();
  std::vector<std::uint16_t> wide(n);
  std::vector<float> halves(n);
  for (std::size_t v = 0; v < n; ++v) {
    wide[v] = static_cast<std::uint16_t>(40000 + 7 * v);
    halves[v] = -1000.0f + 0.5f * static_cast<float>(v);
  }
  const auto path = (scratchDir() / "as_received.nrrd").string();
  ASSERT_TRUE(writeNrrdVoxels(g, VoxelType::kUInt16, reinterpret_cast<const char*>(wide.data()),
                              2 * n, path)
                  .ok());
  auto out = readNrrd(path);
  ASSERT_TRUE(out.ok()) << out.error().message;
  EXPECT_EQ(out->geometry.dims, g.dims);
  EXPECT_LT((out->geometry.ijkToLps() - g.ijkToLps()).cwiseAbs().maxCoeff(), 1e-12);
  for (std::size_t v = 0; v < n; ++v)
    ASSERT_EQ(out->voxels[v] * out->value_scale + out->value_offset, wide[v]) << v;
  ASSERT_TRUE(writeNrrdVoxels(g, VoxelType::kFloat, reinterpret_cast<const char*>(halves.data()),
                              4 * n, path)
                  .ok());
  out = readNrrd(path);
  ASSERT_TRUE(out.ok()) << out.error().message;
  for (std::size_t v = 0; v < n; ++v)
    ASSERT_DOUBLE_EQ(out->voxels[v] * out->value_scale + out->value_offset, halves[v]) << v;

  const auto short_buffer = writeNrrdVoxels(
      g, VoxelType::kFloat, reinterpret_cast<const char*>(halves.data()), 4 * n - 4, path);
  ASSERT_FALSE(short_buffer.ok());
  EXPECT_NE(short_buffer.error().message.find("float"), std::string::npos);
  Geometry skewed = g;
  skewed.direction(0, 1) += 0.2;
  EXPECT_FALSE(writeNrrdVoxels(skewed, VoxelType::kFloat,
                               reinterpret_cast<const char*>(halves.data()), 4 * n, path)
                   .ok());
}

TEST(Nrrd, WriteRejectsInconsistentVolume) {
  Volume in = obliqueVolume();
  in.voxels.pop_back();
  const auto s = writeNrrd(in, (scratchDir() / "bad.nrrd").string());
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument);
}

TEST(Nrrd, ReadVolumeFileDispatchesByExtension) {
  const auto dir = scratchDir();
  const auto path = writeFile(dir / "CT.NRRD", slicerHeader("short", "raw"), int16Le(refValues()));
  const auto v = readVolumeFile(path);
  ASSERT_TRUE(v.ok()) << v.error().message;
  expectRefVolume(*v);
  const auto d = readVolumeFile((dir / "slice.dcm").string());
  ASSERT_FALSE(d.ok());
  EXPECT_EQ(d.error().code, ErrorCode::kUnsupported);
  EXPECT_NE(d.error().message.find("DICOM reader"), std::string::npos);
}

struct BadCase {
  const char* name;
  std::string header;
  Bytes data;
  ErrorCode code;
  const char* says;
};

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

TEST(Nrrd, MalformedFilesGiveErrorsNamingFileAndProblem) {
  const std::string good = slicerHeader("short", "raw");
  const Bytes data = int16Le(refValues());
  Bytes garbage(700);
  for (std::size_t n = 0; n < garbage.size(); ++n)
    garbage[n] = static_cast<std::uint8_t>(n * 131 + 7);
  Bytes half_gzip = gzip(data);
  half_gzip.resize(half_gzip.size() / 2);
  const std::vector<BadCase> cases = {
      {"truncated", good, Bytes(data.begin(), data.begin() + 100), ErrorCode::kFormat, "shorter"},
      {"no_data", good, {}, ErrorCode::kFormat, "shorter"},
      {"missing_sizes", replaced(good, "sizes: 3 4 5\n", ""), data, ErrorCode::kFormat, "sizes"},
      {"missing_type", replaced(good, "type: short\n", ""), data, ErrorCode::kFormat, "type"},
      {"missing_endian", replaced(good, "endian: little\n", ""), data, ErrorCode::kFormat,
       "endian"},
      {"missing_directions",
       replaced(good, "space directions: (0.5,0,0) (0,0.75,0) (0,0,2.5)\n", ""), data,
       ErrorCode::kFormat, "space directions"},
      {"zero_spacing", replaced(good, "(0,0.75,0)", "(0,0,0)"), data, ErrorCode::kFormat, "zero"},
      {"non_orthonormal", replaced(good, "(0,0.75,0)", "(0.5,0.75,0)"), data, ErrorCode::kFormat,
       "orthonormal"},
      {"nan_direction", replaced(good, "(0,0.75,0)", "(0,nan,0)"), data, ErrorCode::kFormat,
       "space directions"},
      {"ten_gigabytes", replaced(good, "sizes: 3 4 5", "sizes: 100000 100000 1"), data,
       ErrorCode::kFormat, "exceed"},
      {"two_gigabytes_raw", replaced(good, "sizes: 3 4 5", "sizes: 1024 1024 1024"), data,
       ErrorCode::kFormat, "shorter"},
      {"two_gigabytes_gzip",
       replaced(replaced(good, "sizes: 3 4 5", "sizes: 1024 1024 1024"), "encoding: raw",
                "encoding: gzip"),
       gzip(data), ErrorCode::kFormat, "shorter"},
      {"negative_size", replaced(good, "sizes: 3 4 5", "sizes: 3 -4 5"), data, ErrorCode::kFormat,
       "sizes"},
      {"two_sizes", replaced(good, "sizes: 3 4 5", "sizes: 3 4"), data, ErrorCode::kFormat,
       "sizes"},
      {"bzip2", replaced(good, "encoding: raw", "encoding: bzip2"), data, ErrorCode::kUnsupported,
       "bzip2"},
      {"bad_encoding", replaced(good, "encoding: raw", "encoding: zip-zap"), data,
       ErrorCode::kUnsupported, "zip-zap"},
      {"bad_type", replaced(good, "type: short", "type: block"), data, ErrorCode::kUnsupported,
       "block"},
      {"dimension_4", replaced(good, "dimension: 3", "dimension: 4"), data, ErrorCode::kUnsupported,
       "dimension"},
      {"scanner_space", replaced(good, "left-posterior-superior", "scanner-xyz"), data,
       ErrorCode::kUnsupported, "scanner-xyz"},
      {"vector_kind", replaced(good, "kinds: domain", "kinds: vector"), data,
       ErrorCode::kUnsupported, "kinds"},
      {"corrupt_gzip", replaced(good, "encoding: raw", "encoding: gzip"), garbage,
       ErrorCode::kFormat, "corrupt"},
      {"truncated_gzip", replaced(good, "encoding: raw", "encoding: gzip"), half_gzip,
       ErrorCode::kFormat, "shorter"},
      {"garbage", "", garbage, ErrorCode::kFormat, "not a NRRD"},
      {"empty", "", {}, ErrorCode::kFormat, "not a NRRD"},
      {"no_blank_line", good.substr(0, good.size() - 1), {}, ErrorCode::kFormat, "blank line"},
      {"missing_data_file",
       replaced(good, "encoding: raw\n", "encoding: raw\ndata file: no.raw\n"),
       {},
       ErrorCode::kIo,
       "no.raw"},
  };
  const auto dir = scratchDir();
  for (const auto& c : cases) {
    const auto path = writeFile(dir / (std::string(c.name) + ".nrrd"), c.header, c.data);
    const auto v = readNrrd(path);
    ASSERT_FALSE(v.ok()) << c.name;
    EXPECT_EQ(v.error().code, c.code) << c.name << ": " << v.error().message;
    EXPECT_NE(v.error().message.find(path), std::string::npos) << c.name;
    EXPECT_NE(v.error().message.find(c.says), std::string::npos)
        << c.name << ": " << v.error().message;
  }
  const auto missing = readNrrd((dir / "does_not_exist.nrrd").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kIo);
}

}  // namespace
}  // namespace ignav::volume
