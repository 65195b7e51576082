// POLYDATA against libOpenIGTLink's PolyDataMessage (an implementation that is not ours): what we
// send it reads with its CRC check, point by point, cell by cell, attribute by attribute; what it
// packs we decode; sizes that lie are refused by name, the next message read.
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <list>
#include <string>
#include <vector>

#include <igtlPolyDataMessage.h>

#include "ignav/igtl/message.hpp"
#include "igtl_readback.hpp"

namespace ignav::igtl {
namespace {

// A tetrahedron's four faces, a polyline through three of its points, a vertex and a strip;
// per-point scalars and normals, and per-cell scalars if `cell_data` (the names' lengths with their
// NULs add up to an odd number: the padding is exercised). libOpenIGTLink's C code (1.11 and
// upstream's) takes every attribute type but point scalars, vectors and normals for a tensor of
// nine components, so it misreads cell data: it is checked against our own reading only.
PolyData tetrahedron(bool cell_data = false) {
  PolyData p;
  p.points = {0, 0, 0, 10.5f, 0, 0, 0, 20.25f, 0, 0, 0, -30.125f};
  p.polygons = {3, 0, 2, 1, 3, 0, 1, 3, 3, 0, 3, 2, 3, 1, 2, 3};
  p.lines = {3, 0, 1, 2};
  p.vertices = {1, 3};
  p.strips = {4, 0, 1, 2, 3};
  PolyAttribute depth;
  depth.type = 0x00;
  depth.name = "Depth";
  depth.values = {1.5f, -2.0f, 3.25f, 4.0f};
  PolyAttribute id;
  id.type = 0x10;
  id.name = "TargetId";
  id.values = {1, 2, 3, 4, 5, 6, 7};  // 4 polygons + 1 line + 1 vertex + 1 strip
  PolyAttribute normals;
  normals.type = 0x02;
  normals.components = 3;
  normals.name = "Normals";
  for (int i = 0; i < 12; ++i)
    normals.values.push_back(0.25f * static_cast<float>(i) - 1.0f);
  p.attributes = {depth, normals};
  if (cell_data) p.attributes.push_back(id);
  return p;
}

std::vector<std::uint32_t> cellsOf(::igtl::PolyDataCellArray* cells) {
  std::vector<std::uint32_t> out;
  if (cells == nullptr) return out;
  for (unsigned int c = 0; c < cells->GetNumberOfCells(); ++c) {
    std::list<igtlUint32> cell;
    cells->GetCell(c, cell);
    out.push_back(static_cast<std::uint32_t>(cell.size()));
    out.insert(out.end(), cell.begin(), cell.end());
  }
  return out;
}

::igtl::PolyDataCellArray::Pointer cellArray(const std::vector<std::uint32_t>& cells) {
  auto out = ::igtl::PolyDataCellArray::New();
  for (std::size_t at = 0; at < cells.size(); at += cells[at] + 1) {
    std::list<igtlUint32> cell(cells.begin() + static_cast<std::ptrdiff_t>(at + 1),
                               cells.begin() + static_cast<std::ptrdiff_t>(at + 1 + cells[at]));
    out->AddCell(cell);
  }
  return out;
}

Expected<Message> decodeOne(const std::string& bytes) {
  Decoder decoder;
  decoder.feed(bytes.data(), bytes.size());
  auto m = decoder.next();
  if (!m) return makeError(ErrorCode::kFormat, "nothing decoded");
  return *m;
}

TEST(IgtlPolyData, WhatWeSendLibOpenIGTLinkReads) {
  const PolyData p = tetrahedron();
  auto bytes = encode(polyDataMessage("Prostate", p));
  ASSERT_TRUE(bytes.ok()) << bytes.error().message;
  auto m = igtl_test::readBack<::igtl::PolyDataMessage>(*bytes);
  EXPECT_STREQ(m->GetDeviceName(), "Prostate");
  auto points = m->GetPoints();
  ASSERT_NE(points, nullptr);
  ASSERT_EQ(points->GetNumberOfPoints(), 4);
  for (unsigned int i = 0; i < 4; ++i) {
    igtlFloat32 xyz[3];
    points->GetPoint(i, xyz);
    for (int a = 0; a < 3; ++a)
      EXPECT_EQ(xyz[a], p.points[3 * i + a]) << i << "," << a;
  }
  EXPECT_EQ(cellsOf(m->GetPolygons()), p.polygons);
  EXPECT_EQ(cellsOf(m->GetLines()), p.lines);
  EXPECT_EQ(cellsOf(m->GetVertices()), p.vertices);
  EXPECT_EQ(cellsOf(m->GetTriangleStrips()), p.strips);
  ASSERT_EQ(m->GetNumberOfAttributes(), 2);
  for (unsigned int a = 0; a < 2; ++a) {
    auto* att = m->GetAttribute(a);
    EXPECT_EQ(att->GetName(), p.attributes[a].name);
    EXPECT_EQ(att->GetType(), p.attributes[a].type);
    EXPECT_EQ(att->GetNumberOfComponents(), p.attributes[a].components);
    std::vector<igtlFloat32> values(att->GetSize() * att->GetNumberOfComponents());
    att->GetData(values.data());
    EXPECT_EQ(values, p.attributes[a].values) << att->GetName();
  }
}

TEST(IgtlPolyData, WhatLibOpenIGTLinkPacksWeDecode) {
  const PolyData p = tetrahedron();
  auto m = ::igtl::PolyDataMessage::New();
  m->SetDeviceName("FeasibleVolume");
  auto points = ::igtl::PolyDataPointArray::New();
  for (std::size_t i = 0; i < p.points.size(); i += 3)
    points->AddPoint(p.points[i], p.points[i + 1], p.points[i + 2]);
  m->SetPoints(points);
  m->SetPolygons(cellArray(p.polygons));
  m->SetLines(cellArray(p.lines));
  m->SetVertices(cellArray(p.vertices));
  m->SetTriangleStrips(cellArray(p.strips));
  for (const auto& a : p.attributes) {
    auto att = ::igtl::PolyDataAttribute::New();
    att->SetType(a.type, a.components);
    att->SetName(a.name.c_str());
    att->SetSize(static_cast<igtlUint32>(a.values.size() / a.components));
    std::vector<igtlFloat32> values(a.values.begin(), a.values.end());
    att->SetData(values.data());
    m->AddAttribute(att);
  }
  auto decoded = decodeOne(igtl_test::packed(m));
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->type, "POLYDATA");
  EXPECT_EQ(decoded->device_name, "FeasibleVolume");
  EXPECT_EQ(decoded->poly.points, p.points);
  EXPECT_EQ(decoded->poly.polygons, p.polygons);
  EXPECT_EQ(decoded->poly.lines, p.lines);
  EXPECT_EQ(decoded->poly.vertices, p.vertices);
  EXPECT_EQ(decoded->poly.strips, p.strips);
  ASSERT_EQ(decoded->poly.attributes.size(), 2u);
  for (std::size_t a = 0; a < 2; ++a) {
    EXPECT_EQ(decoded->poly.attributes[a].name, p.attributes[a].name);
    EXPECT_EQ(decoded->poly.attributes[a].type, p.attributes[a].type);
    EXPECT_EQ(decoded->poly.attributes[a].components, p.attributes[a].components);
    EXPECT_EQ(decoded->poly.attributes[a].values, p.attributes[a].values);
  }
}

TEST(IgtlPolyData, AVersionTwoMessageWithCellDataReadsBack) {
  Message m = polyDataMessage("PlannedPaths", tetrahedron(true));
  m.header_version = 2;
  m.message_id = 7;
  m.metadata = {{"Kind", kUsAscii, "path"}, {"Units", kUsAscii, "mm"}};
  auto bytes = encode(m);
  ASSERT_TRUE(bytes.ok()) << bytes.error().message;
  auto decoded = decodeOne(*bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->message_id, 7u);
  ASSERT_NE(metaDataValue(*decoded, "Kind"), nullptr);
  EXPECT_EQ(*metaDataValue(*decoded, "Kind"), "path");
  EXPECT_EQ(decoded->poly.polygons, m.poly.polygons);
  ASSERT_EQ(decoded->poly.attributes.size(), 3u);
  EXPECT_EQ(decoded->poly.attributes[2].name, "TargetId");
  EXPECT_TRUE(decoded->poly.attributes[2].perCell());
  EXPECT_EQ(decoded->poly.attributes[2].values, m.poly.attributes[2].values);
}

TEST(IgtlPolyData, WhatCannotBeSentIsRefusedByName) {
  const auto refused = [](PolyData p, const char* why) {
    auto bytes = encode(polyDataMessage("Bad", std::move(p)));
    ASSERT_FALSE(bytes.ok()) << why;
    EXPECT_NE(bytes.error().message.find("POLYDATA 'Bad'"), std::string::npos)
        << bytes.error().message;
  };
  PolyData p = tetrahedron(true);
  p.polygons.back() = 4;  // a point that is not there
  refused(p, "index past the points");
  p = tetrahedron();
  p.lines = {5, 0, 1};  // a count past the array's end
  refused(p, "count past the end");
  p = tetrahedron(true);
  p.attributes[2].values.pop_back();  // one cell without its value
  refused(p, "attribute short of a cell");
  p = tetrahedron();
  p.attributes[1].components = 2;  // normals have three
  refused(p, "normals of two components");
  p = tetrahedron();
  p.points[4] = std::numeric_limits<float>::quiet_NaN();
  refused(p, "NaN point");
}

// Our own bytes with one field changed, the CRC made right again: only the sizes lie.
std::string withBody(std::string bytes, std::size_t at, std::uint64_t value, int width) {
  std::string field;
  appendBigEndian(field, value, width);
  std::memcpy(bytes.data() + kHeaderBytes + at, field.data(), static_cast<std::size_t>(width));
  Header h = readHeader(bytes.data());
  h.crc = crc64(std::string_view(bytes).substr(kHeaderBytes));
  const std::string header = writeHeader(h);
  std::memcpy(bytes.data(), header.data(), kHeaderBytes);
  return bytes;
}

TEST(IgtlPolyData, SizesThatLieAreRefusedAndTheNextMessageIsRead) {
  auto good = encode(polyDataMessage("Prostate", tetrahedron(true)));
  ASSERT_TRUE(good.ok());
  const struct {
    std::size_t at;
    std::uint64_t value;
    int width;
    const char* says;
  } lies[] = {
      {0, 0xffffffffULL, 4, "points"},      // 2^32 - 1 points in a small body
      {20, 5, 4, "polygons"},               // five polygons in an array of four
      {24, 63, 4, "multiple of 4"},         // a cell array's size not in uint32s
      {36, 0x40000000ULL, 4, "attribute"},  // 2^30 attributes
      {kPolyDataHeaderBytes + 48 + 64 + 16 + 8 + 20 + 6 + 2, 0xffffffffULL, 4, "attribute"},
  };
  auto status = encode(statusMessage("After", StatusCode::kOk));
  ASSERT_TRUE(status.ok());
  for (const auto& lie : lies) {
    Decoder decoder;
    const std::string bytes = withBody(*good, lie.at, lie.value, lie.width) + *status;
    decoder.feed(bytes.data(), bytes.size());
    auto first = decoder.next();
    ASSERT_TRUE(first.has_value());
    ASSERT_FALSE(first->ok()) << lie.says;
    EXPECT_NE(first->error().message.find("POLYDATA message 'Prostate'"), std::string::npos)
        << first->error().message;
    EXPECT_NE(first->error().message.find(lie.says), std::string::npos) << first->error().message;
    auto next = decoder.next();
    ASSERT_TRUE(next.has_value() && next->ok()) << lie.says;
    EXPECT_EQ((*next)->device_name, "After");
  }
}

}  // namespace
}  // namespace ignav::igtl
