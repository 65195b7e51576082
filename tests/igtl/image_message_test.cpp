// IMAGE against libOpenIGTLink's ImageMessage (an implementation that is not ours): what we encode
// it reads with its CRC check, geometry and voxels; what it packs we decode, in either byte order.
// The centre convention (OpenIGTLink gives the volume's centre, (size - 1) / 2 from voxel 0, as
// OpenIGTLinkIO converts it) is checked on an oblique, anisotropic volume.
#include <gtest/gtest.h>

#include <cstring>

#include <igtlImageMessage.h>
#include <igtlMessageHeader.h>
#include <Eigen/Geometry>

#include "ignav/igtl/message.hpp"
#include "igtl_readback.hpp"
#include "v3_peer.hpp"

namespace ignav::igtl {
namespace {

// An oblique volume: 20° about S then 10° about R, spacing 0.7 x 0.9 x 2.5 mm, 5 x 4 x 3 voxels.
Eigen::Matrix4d obliqueIjkToRas() {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  const Eigen::Matrix3d r = (Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(0.17, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  m.topLeftCorner<3, 3>() = r * Eigen::Vector3d(0.7, 0.9, 2.5).asDiagonal();
  m.topRightCorner<3, 1>() = Eigen::Vector3d(-40.25, 12.5, -90.0);
  return m;
}

Image int16Image(const std::array<int, 3>& size) {
  auto voxels = std::make_shared<std::vector<std::int16_t>>();
  for (int n = 0; n < size[0] * size[1] * size[2]; ++n)
    voxels->push_back(static_cast<std::int16_t>(n * 37 - 1000));
  Image image;
  image.size = size;
  image.scalar_type = ScalarType::kInt16;
  image.ijk_to_mm = obliqueIjkToRas();
  image.data_bytes = voxels->size() * 2;
  image.data = std::shared_ptr<const char>(voxels, reinterpret_cast<const char*>(voxels->data()));
  return image;
}

TEST(IgtlImage, WhatWeEncodeLibOpenIGTLinkReads) {
  const Image image = int16Image({5, 4, 3});
  auto bytes = encode(imageMessage("PlanningCT", image));
  ASSERT_TRUE(bytes.ok()) << bytes.error().message;
  auto m = igtl_test::readBack<::igtl::ImageMessage>(*bytes);
  int size[3];
  m->GetDimensions(size);
  EXPECT_EQ(size[0], 5);
  EXPECT_EQ(size[1], 4);
  EXPECT_EQ(size[2], 3);
  EXPECT_EQ(m->GetScalarType(), ::igtl::ImageMessage::TYPE_INT16);
  EXPECT_EQ(m->GetEndian(), ::igtl::ImageMessage::ENDIAN_LITTLE);
  EXPECT_EQ(m->GetCoordinateSystem(), ::igtl::ImageMessage::COORDINATE_RAS);
  float spacing[3];
  m->GetSpacing(spacing);
  EXPECT_NEAR(spacing[0], 0.7, 1e-6);
  EXPECT_NEAR(spacing[1], 0.9, 1e-6);
  EXPECT_NEAR(spacing[2], 2.5, 1e-6);
  ::igtl::Matrix4x4 matrix;
  m->GetMatrix(matrix);
  const Eigen::Matrix4d expected = obliqueIjkToRas();
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      EXPECT_NEAR(matrix[r][c], expected(r, c) / expected.col(c).head<3>().norm(), 1e-6);
  // Its origin is the volume's centre: voxel (2, 1.5, 1).
  const Eigen::Vector3d centre = (expected * Eigen::Vector4d(2, 1.5, 1, 1)).head<3>();
  for (int r = 0; r < 3; ++r)
    EXPECT_NEAR(matrix[r][3], centre[r], 1e-4);
  ASSERT_EQ(m->GetImageSize(), 5 * 4 * 3 * 2);
  EXPECT_EQ(std::memcmp(m->GetScalarPointer(), image.data.get(), image.data_bytes), 0);
}

TEST(IgtlImage, WhatLibOpenIGTLinkPacksWeDecodeInEitherByteOrder) {
  for (const int endian : {::igtl::ImageMessage::ENDIAN_LITTLE, ::igtl::ImageMessage::ENDIAN_BIG}) {
    auto m = ::igtl::ImageMessage::New();
    m->SetDeviceName("ConfirmationCT");
    m->SetDimensions(5, 4, 3);
    m->SetSpacing(0.7f, 0.9f, 2.5f);
    m->SetScalarTypeToInt16();
    m->SetEndian(endian);
    m->SetCoordinateSystem(::igtl::ImageMessage::COORDINATE_LPS);
    const Eigen::Matrix4d ijk = obliqueIjkToRas();
    ::igtl::Matrix4x4 matrix;
    ::igtl::IdentityMatrix(matrix);
    const Eigen::Vector3d centre = (ijk * Eigen::Vector4d(2, 1.5, 1, 1)).head<3>();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c)
        matrix[r][c] = static_cast<float>(ijk(r, c) / ijk.col(c).head<3>().norm());
      matrix[r][3] = static_cast<float>(centre[r]);
    }
    m->SetMatrix(matrix);
    m->AllocateScalars();
    auto* voxels = static_cast<unsigned char*>(m->GetScalarPointer());
    for (int n = 0; n < 60; ++n) {
      const auto v = static_cast<std::uint16_t>(static_cast<std::int16_t>(n * 37 - 1000));
      const bool big = endian == ::igtl::ImageMessage::ENDIAN_BIG;
      voxels[2 * n] = static_cast<unsigned char>(big ? v >> 8 : v & 0xff);
      voxels[2 * n + 1] = static_cast<unsigned char>(big ? v & 0xff : v >> 8);
    }
    m->Pack();
    Decoder d(1024, 1 << 20);
    d.feed(static_cast<const char*>(m->GetPackPointer()),
           static_cast<std::size_t>(m->GetPackSize()));
    auto next = d.next();
    ASSERT_TRUE(next.has_value() && next->ok()) << (next ? next->error().message : "nothing");
    const Image& image = next->value().image;
    EXPECT_EQ(image.size, (std::array<int, 3>{5, 4, 3}));
    EXPECT_FALSE(image.ras);
    EXPECT_LT((image.ijk_to_mm - ijk).cwiseAbs().maxCoeff(), 1e-4) << image.ijk_to_mm;
    ASSERT_EQ(image.data_bytes, 120u);
    for (int n = 0; n < 60; ++n) {
      std::int16_t v;
      std::memcpy(&v, image.data.get() + 2 * n, 2);
      ASSERT_EQ(v, n * 37 - 1000) << "voxel " << n << " endian " << endian;
    }
  }
}

TEST(IgtlImage, AVersion2ImageIsByteForByteTheDescription) {
  Message m = imageMessage("Dose", int16Image({2, 2, 1}));
  m.header_version = 2;
  m.message_id = 77;
  m.metadata = {{"Units", kUsAscii, "HU"}};
  auto ours = encode(m);
  ASSERT_TRUE(ours.ok()) << ours.error().message;
  // The image header as the description lays it out, from the peer's own byte assembly.
  const Eigen::Matrix4d ijk = obliqueIjkToRas();
  const Eigen::Vector3d centre = (ijk * Eigen::Vector4d(0.5, 0.5, 0, 1)).head<3>();
  std::string header = igtl3_test::be(1, 2) + std::string{1, 4, 2, 1} + igtl3_test::be(2, 2) +
                       igtl3_test::be(2, 2) + igtl3_test::be(1, 2);
  const auto appendFloat = [&](double v) {
    const auto f = static_cast<float>(v);
    std::uint32_t bits;
    std::memcpy(&bits, &f, 4);
    header += igtl3_test::be(bits, 4);
  };
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r)
      appendFloat(ijk(r, c));
  for (int r = 0; r < 3; ++r)
    appendFloat(centre[r]);
  header +=
      igtl3_test::be(0, 6) + igtl3_test::be(2, 2) + igtl3_test::be(2, 2) + igtl3_test::be(1, 2);
  std::string voxels;
  for (const int v : {-1000, -963, -926, -889})
    voxels += std::string{static_cast<char>(v & 0xff), static_cast<char>((v >> 8) & 0xff)};
  EXPECT_EQ(*ours, igtl3_test::frame(2, "IMAGE", "Dose", 0,
                                     igtl3_test::body2(header + voxels, 77, {{"Units", 3, "HU"}})));
}

TEST(IgtlImage, ImagesThatCannotBeTakenAreRefusedByName) {
  auto good = encode(imageMessage("CT", int16Image({5, 4, 3})));
  ASSERT_TRUE(good.ok());
  using Edits = std::vector<std::pair<std::size_t, std::string>>;
  const auto refusal = [](std::string bytes, const Edits& edits) {
    for (const auto& [at, value] : edits)
      bytes.replace(kHeaderBytes + at, value.size(), value);
    // The CRC is made right again: what is judged is the content.
    const std::string body = bytes.substr(kHeaderBytes);
    bytes.replace(50, 8, igtl3_test::be(igtl3_test::referenceCrc(body), 8));
    Decoder d(1024, 1 << 20);
    d.feed(bytes.data(), bytes.size());
    auto next = d.next();
    return next && !next->ok() ? next->error().message : std::string("accepted");
  };
  EXPECT_NE(refusal(*good, {{3, std::string(1, '\x09')}}).find("scalar type 9"), std::string::npos);
  EXPECT_NE(refusal(*good, {{60, igtl3_test::be(1, 2)}}).find("partial image"), std::string::npos);
  EXPECT_NE(refusal(*good, {{6, igtl3_test::be(6, 2)}, {66, igtl3_test::be(6, 2)}})
                .find("bytes of voxels"),
            std::string::npos);
  EXPECT_NE(refusal(*good, {{12, std::string(36, '\0')}}).find("do not span"), std::string::npos);
  // Bigger than the image limit: refused before it is held.
  Decoder small(64, 100);
  small.feed(good->data(), kHeaderBytes);
  auto next = small.next();
  ASSERT_TRUE(next.has_value());
  EXPECT_FALSE(next->ok());
  // Our encoder refuses what the wire cannot carry.
  Image wrong = int16Image({5, 4, 3});
  wrong.data_bytes = 10;
  EXPECT_FALSE(encode(imageMessage("CT", wrong)).ok());
  wrong = int16Image({5, 4, 3});
  wrong.size = {70000, 1, 1};
  EXPECT_FALSE(encode(imageMessage("CT", wrong)).ok());
}

// A scan larger than the running-CRC threshold, fed in odd-sized reads: read whole and equal when
// intact; one voxel byte flipped under the same header is refused as a CRC mismatch, and the
// message after it is read.
TEST(IgtlImage, ALargeImageFedInPiecesIsCheckedAsItArrives) {
  const Image image = int16Image({128, 96, 50});  // 1.2 MB of voxels
  ASSERT_GT(image.data_bytes, kLargeBodyBytes);
  Message m = imageMessage("ConfirmationCT", image);
  m.header_version = 2;
  m.metadata = {{"Scanner", kUsAscii, "test"}};
  auto bytes = encode(m);
  ASSERT_TRUE(bytes.ok()) << bytes.error().message;
  auto after = encode(statusMessage("After", StatusCode::kOk));
  ASSERT_TRUE(after.ok());
  std::string damaged = *bytes;
  damaged[damaged.size() / 2] ^= 0x10;
  for (const bool intact : {true, false}) {
    const std::string stream = (intact ? *bytes : damaged) + *after;
    Decoder decoder(64 * 1024, 4u << 20);
    std::vector<Expected<Message>> got;
    for (std::size_t at = 0; at < stream.size(); at += 7919) {
      decoder.feed(stream.data() + at, std::min<std::size_t>(7919, stream.size() - at));
      while (auto next = decoder.next())
        got.push_back(std::move(*next));
    }
    ASSERT_EQ(got.size(), 2u);
    ASSERT_TRUE(got[1].ok());
    EXPECT_EQ(got[1]->device_name, "After");
    if (!intact) {
      ASSERT_FALSE(got[0].ok());
      EXPECT_NE(got[0].error().message.find("IMAGE message 'ConfirmationCT': CRC mismatch"),
                std::string::npos)
          << got[0].error().message;
      continue;
    }
    ASSERT_TRUE(got[0].ok()) << got[0].error().message;
    const Image& read = got[0]->image;
    EXPECT_EQ(read.size, image.size);
    ASSERT_EQ(read.data_bytes, image.data_bytes);
    EXPECT_EQ(std::memcmp(read.data.get(), image.data.get(), image.data_bytes), 0);
    ASSERT_NE(metaDataValue(*got[0], "Scanner"), nullptr);
  }
}

}  // namespace
}  // namespace ignav::igtl
