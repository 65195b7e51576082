// MetaImage files written by hand as ITK's MetaImageIO writes them. The reference for the
// TransformMatrix layout is ITK's reader: SetDirection(i, {m[3i], m[3i+1], m[3i+2]}), i.e. the
// three numbers of row i are the LPS direction of voxel axis i.
#include <gtest/gtest.h>
#include <zlib.h>

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

// 4 x 3 x 2 voxels, value 7 i - 5 j + 300 k - 100.
int refValue(int i, int j, int k) {
  return 7 * i - 5 * j + 300 * k - 100;
}

Bytes int16Bytes(bool big_endian) {
  Bytes b;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 4; ++i) {
        const auto u = static_cast<std::uint16_t>(static_cast<std::int16_t>(refValue(i, j, k)));
        const auto hi = static_cast<std::uint8_t>(u >> 8), lo = static_cast<std::uint8_t>(u & 0xff);
        b.push_back(big_endian ? hi : lo);
        b.push_back(big_endian ? lo : hi);
      }
  return b;
}

// As itk::MetaImageIO writes a 3D short image; axis i points to +P, j to +R, k to +S.
std::string itkHeader(const std::string& data_file, const std::string& type = "MET_SHORT",
                      const std::string& msb = "False", const std::string& compressed = "False") {
  return "ObjectType = Image\n"
         "NDims = 3\n"
         "BinaryData = True\n"
         "BinaryDataByteOrderMSB = " +
         msb +
         "\n"
         "CompressedData = " +
         compressed +
         "\n"
         "TransformMatrix = 0 1 0 -1 0 0 0 0 1\n"
         "Offset = -10 20 30\n"
         "CenterOfRotation = 0 0 0\n"
         "AnatomicalOrientation = ALI\n"
         "ElementSpacing = 0.5 0.75 2.5\n"
         "DimSize = 4 3 2\n"
         "ElementType = " +
         type +
         "\n"
         "ElementDataFile = " +
         data_file + "\n";
}

void expectRef(const Expected<Volume>& v) {
  ASSERT_TRUE(v.ok()) << v.error().message;
  ASSERT_EQ(v->geometry.dims, (std::array<int, 3>{4, 3, 2}));
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 4; ++i)
        ASSERT_DOUBLE_EQ(v->valueAt(i, j, k), refValue(i, j, k));
  // Voxel (1, 2, 1) = Offset + 1 * 0.5 * (0,1,0) + 2 * 0.75 * (-1,0,0) + 1 * 2.5 * (0,0,1).
  const Eigen::Vector3d p = v->geometry.toLps({1, 2, 1});
  EXPECT_NEAR(p.x(), -11.5, 1e-12);
  EXPECT_NEAR(p.y(), 20.5, 1e-12);
  EXPECT_NEAR(p.z(), 32.5, 1e-12);
}

TEST(MetaImage, ItkMhaLocalShortGivesValuesAndLpsGeometry) {
  expectRef(
      readMetaImage(writeFile(scratchDir() / "ct.mha", itkHeader("LOCAL"), int16Bytes(false))));
}

TEST(MetaImage, MhdWithBigEndianRawFile) {
  const auto dir = scratchDir();
  writeFile(dir / "ct.raw", "", int16Bytes(true));
  expectRef(readMetaImage(writeFile(dir / "ct.mhd", itkHeader("ct.raw", "MET_SHORT", "True"))));
}

TEST(MetaImage, CompressedDataIsZlib) {
  const Bytes raw = int16Bytes(false);
  Bytes z(compressBound(static_cast<uLong>(raw.size())));
  uLongf z_size = static_cast<uLongf>(z.size());
  ASSERT_EQ(compress(z.data(), &z_size, raw.data(), static_cast<uLong>(raw.size())), Z_OK);
  z.resize(z_size);
  std::string header = itkHeader("LOCAL", "MET_SHORT", "False", "True");
  header.insert(header.find("TransformMatrix"),
                "CompressedDataSize = " + std::to_string(z_size) + "\n");
  expectRef(readMetaImage(writeFile(scratchDir() / "z.mha", header, z)));
}

TEST(MetaImage, FloatAndCharTypes) {
  Bytes f;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 4; ++i) {
        const float v = static_cast<float>(refValue(i, j, k));
        std::uint8_t b[4];
        std::memcpy(b, &v, 4);
        f.insert(f.end(), b, b + 4);
      }
  expectRef(readMetaImage(writeFile(scratchDir() / "f.mha", itkHeader("LOCAL", "MET_FLOAT"), f)));
  Bytes c(24);
  for (std::size_t n = 0; n < c.size(); ++n)
    c[n] = static_cast<std::uint8_t>(n * 10);  // 0..230
  const auto v =
      readMetaImage(writeFile(scratchDir() / "c.mha", itkHeader("LOCAL", "MET_CHAR"), c));
  ASSERT_TRUE(v.ok()) << v.error().message;
  EXPECT_DOUBLE_EQ(v->valueAt(3, 2, 1), 230 - 256);  // signed char
  const auto u =
      readMetaImage(writeFile(scratchDir() / "u.mha", itkHeader("LOCAL", "MET_UCHAR"), c));
  ASSERT_TRUE(u.ok()) << u.error().message;
  EXPECT_DOUBLE_EQ(u->valueAt(3, 2, 1), 230);
}

TEST(MetaImage, ReadVolumeFileDispatchesMha) {
  expectRef(
      readVolumeFile(writeFile(scratchDir() / "ct.mha", itkHeader("LOCAL"), int16Bytes(false))));
}

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

TEST(MetaImage, MalformedFilesGiveErrorsNamingFileAndProblem) {
  struct Case {
    const char* name;
    std::string header;
    Bytes data;
    ErrorCode code;
    const char* says;
  };
  const std::string good = itkHeader("LOCAL");
  const Bytes data = int16Bytes(false);
  Bytes garbage(500);
  for (std::size_t n = 0; n < garbage.size(); ++n)
    garbage[n] = static_cast<std::uint8_t>(n * 97 + 3);
  const std::vector<Case> cases = {
      {"truncated", good, Bytes(data.begin(), data.begin() + 30), ErrorCode::kFormat, "shorter"},
      {"missing_dimsize", replaced(good, "DimSize = 4 3 2\n", ""), data, ErrorCode::kFormat,
       "DimSize"},
      {"missing_type", replaced(good, "ElementType = MET_SHORT\n", ""), data, ErrorCode::kFormat,
       "ElementType"},
      {"ndims_2", replaced(good, "NDims = 3", "NDims = 2"), data, ErrorCode::kUnsupported, "NDims"},
      {"zero_spacing", replaced(good, "0.5 0.75 2.5", "0.5 0 2.5"), data, ErrorCode::kFormat,
       "spacing"},
      {"non_orthonormal", replaced(good, "0 1 0 -1 0 0 0 0 1", "0 1 0 1 1 0 0 0 1"), data,
       ErrorCode::kFormat, "orthonormal"},
      {"short_matrix", replaced(good, "0 1 0 -1 0 0 0 0 1", "0 1 0 -1 0 0"), data,
       ErrorCode::kFormat, "TransformMatrix"},
      {"ten_gigabytes", replaced(good, "DimSize = 4 3 2", "DimSize = 100000 100000 1"), data,
       ErrorCode::kFormat, "exceed"},
      {"two_gigabytes", replaced(good, "DimSize = 4 3 2", "DimSize = 1024 1024 1024"), data,
       ErrorCode::kFormat, "shorter"},
      {"bad_type", replaced(good, "MET_SHORT", "MET_SHORT_ARRAY"), data, ErrorCode::kUnsupported,
       "MET_SHORT_ARRAY"},
      {"corrupt_zlib", replaced(good, "CompressedData = False", "CompressedData = True"), garbage,
       ErrorCode::kFormat, "corrupt"},
      {"not_image", replaced(good, "ObjectType = Image", "ObjectType = Tube"), data,
       ErrorCode::kUnsupported, "Tube"},
      {"missing_raw_file",
       replaced(good, "= LOCAL", "= absent.raw"),
       {},
       ErrorCode::kIo,
       "absent.raw"},
      {"no_data_file_line", replaced(good, "ElementDataFile = LOCAL\n", ""), data,
       ErrorCode::kFormat, "not a MetaImage header line"},
      {"garbage", "", garbage, ErrorCode::kFormat, "not a MetaImage header line"},
      {"empty", "", {}, ErrorCode::kFormat, "ElementDataFile"},
  };
  const auto dir = scratchDir();
  for (const auto& c : cases) {
    const auto path = writeFile(dir / (std::string(c.name) + ".mha"), c.header, c.data);
    const auto v = readMetaImage(path);
    ASSERT_FALSE(v.ok()) << c.name;
    EXPECT_EQ(v.error().code, c.code) << c.name << ": " << v.error().message;
    EXPECT_NE(v.error().message.find(path), std::string::npos) << c.name;
    EXPECT_NE(v.error().message.find(c.says), std::string::npos)
        << c.name << ": " << v.error().message;
  }
}

}  // namespace
}  // namespace ignav::volume
