// TDATA and STT_TDATA against libOpenIGTLink's TrackingDataMessage and StartTrackingDataMessage
// (an implementation that is not ours): what we send it reads with its CRC check, element by
// element; what it packs we decode.
#include <gtest/gtest.h>

#include <cstring>

#include <igtlMessageHeader.h>
#include <igtlTrackingDataMessage.h>
#include <Eigen/Geometry>

#include "ignav/igtl/message.hpp"
#include "igtl_readback.hpp"

namespace ignav::igtl {
namespace {

Eigen::Matrix4d pose() {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  m.topRightCorner<3, 1>() = Eigen::Vector3d(12.25, -33.5, -190.125);
  return m;
}

TEST(IgtlTracking, WhatWeSendLibOpenIGTLinkReads) {
  auto bytes = encode(trackingMessage("NeedleTip", pose()));
  ASSERT_TRUE(bytes.ok()) << bytes.error().message;
  auto m = igtl_test::readBack<::igtl::TrackingDataMessage>(*bytes);
  EXPECT_STREQ(m->GetDeviceType(), "TDATA");
  ASSERT_EQ(m->GetNumberOfTrackingDataElements(), 1);
  ::igtl::TrackingDataElement::Pointer e;
  m->GetTrackingDataElement(0, e);
  EXPECT_STREQ(e->GetName(), "NeedleTip");
  EXPECT_EQ(e->GetType(), ::igtl::TrackingDataElement::TYPE_6D);
  ::igtl::Matrix4x4 matrix;
  e->GetMatrix(matrix);
  const Eigen::Matrix4d expected = pose();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      EXPECT_EQ(matrix[r][c], static_cast<float>(expected(r, c))) << r << "," << c;
}

TEST(IgtlTracking, WhatLibOpenIGTLinkPacksWeDecode) {
  auto m = ::igtl::TrackingDataMessage::New();
  m->SetDeviceName("Tracker");
  const Eigen::Matrix4d p = pose();
  for (const char* name : {"Tool1", "Tool2"}) {
    auto e = ::igtl::TrackingDataElement::New();
    e->SetName(name);
    e->SetType(::igtl::TrackingDataElement::TYPE_6D);
    ::igtl::Matrix4x4 matrix;
    ::igtl::IdentityMatrix(matrix);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        matrix[r][c] = static_cast<float>(p(r, c));
    e->SetMatrix(matrix);
    m->AddTrackingDataElement(e);
  }
  auto start = ::igtl::StartTrackingDataMessage::New();
  start->SetDeviceName("Tracker");
  start->SetResolution(10);
  start->SetCoordinateName("RAS");
  const std::string stream = igtl_test::packed(m) + igtl_test::packed(start);
  Decoder d;
  d.feed(stream.data(), stream.size());
  auto tdata = d.next();
  ASSERT_TRUE(tdata.has_value() && tdata->ok()) << (tdata ? tdata->error().message : "");
  ASSERT_EQ(tdata->value().tracking.size(), 2u);
  EXPECT_EQ(tdata->value().tracking[1].name, "Tool2");
  EXPECT_LT((tdata->value().tracking[1].matrix - p).cwiseAbs().maxCoeff(), 1e-4);
  auto stt = d.next();
  ASSERT_TRUE(stt.has_value() && stt->ok()) << (stt ? stt->error().message : "");
  EXPECT_EQ(stt->value().type, "STT_TDATA");
  EXPECT_EQ(stt->value().stream_interval_ms, 10u);
}

}  // namespace
}  // namespace ignav::igtl
