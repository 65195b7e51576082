// A TRANSFORM's matrix between Eigen and libOpenIGTLink (float32 on the wire), for the test
// clients (brp_client.hpp, brp2013_client.hpp), which talk libOpenIGTLink directly rather than
// through ignav's own codec.
#pragma once

#include <igtlTransformMessage.h>

#include <Eigen/Core>

namespace ignav::igtl_test {

inline void setMatrix(igtl::TransformMessage& m, const Eigen::Matrix4d& matrix) {
  igtl::Matrix4x4 f;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      f[r][c] = static_cast<float>(matrix(r, c));
  m.SetMatrix(f);
}

inline Eigen::Matrix4d matrixOf(igtl::TransformMessage& m) {
  igtl::Matrix4x4 f;
  m.GetMatrix(f);
  Eigen::Matrix4d out;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      out(r, c) = static_cast<double>(f[r][c]);
  return out;
}

}  // namespace ignav::igtl_test
