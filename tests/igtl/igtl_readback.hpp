// libOpenIGTLink (an implementation that is not ours) as the reader and writer of reference for
// the codec's tests.
#pragma once

#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include <igtlMessageBase.h>
#include <igtlMessageHeader.h>

namespace ignav::igtl_test {

// What libOpenIGTLink packs, as bytes.
inline std::string packed(::igtl::MessageBase* m) {
  m->Pack();
  return std::string(static_cast<const char*>(m->GetPackPointer()),
                     static_cast<std::size_t>(m->GetPackSize()));
}

// libOpenIGTLink's reading of our bytes: the header, then the body with its CRC checked.
template <class M>
typename M::Pointer readBack(const std::string& bytes) {
  auto header = ::igtl::MessageHeader::New();
  header->InitPack();
  EXPECT_GE(bytes.size(), static_cast<std::size_t>(header->GetPackSize()));
  std::memcpy(header->GetPackPointer(), bytes.data(), header->GetPackSize());
  header->Unpack();
  auto m = M::New();
  m->SetMessageHeader(header);
  m->AllocatePack();
  EXPECT_EQ(bytes.size(), header->GetPackSize() + m->GetPackBodySize());
  std::memcpy(m->GetPackBodyPointer(), bytes.data() + header->GetPackSize(), m->GetPackBodySize());
  EXPECT_TRUE(m->Unpack(1) & ::igtl::MessageHeader::UNPACK_BODY) << "CRC";
  return m;
}

}  // namespace ignav::igtl_test
