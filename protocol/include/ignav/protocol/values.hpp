// The protocol's plain values shared by every topic (a point, a row-major matrix, per-motor
// triples) and which topic a value travels on. The values themselves: request_types.hpp and
// state_types.hpp, both in types.hpp.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "ignav/protocol/topics.hpp"

namespace ignav::protocol {

// A point, [x, y, z] in the JSON view.
struct Point3 {
  double x = 0.0, y = 0.0, z = 0.0;
};
inline Point3 toPoint3(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}
inline Eigen::Vector3d toEigen(const Point3& p) {
  return {p.x, p.y, p.z};
}
template <typename Points>
std::vector<Point3> toPoints3(const Points& points) {
  std::vector<Point3> out;
  out.reserve(points.size());
  for (const auto& p : points)
    out.push_back(toPoint3(p));
  return out;
}

// A 4x4 matrix as 16 row-major numbers (as it travels and as the JSON view shows it).
using RowMajor4 = std::array<double, 16>;
inline RowMajor4 toRowMajor(const Eigen::Matrix4d& m) {
  RowMajor4 out{};
  for (int i = 0; i < 16; ++i)
    out[static_cast<std::size_t>(i)] = m(i / 4, i % 4);
  return out;
}
inline Eigen::Matrix4d fromRowMajor(const RowMajor4& a) {
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i)
    m(i / 4, i % 4) = a[static_cast<std::size_t>(i)];
  return m;
}

using MotorSteps = std::array<std::int64_t, 3>;  // per motor: θc, zc, zs
using JointValues = std::array<double, 3>;       // θc rad, zc mm, zs mm

// Which topic a value travels on, with which QoS: TopicOf<T>::name, ::qos (declared after each
// value below, in request_types.hpp and state_types.hpp).
template <typename T>
struct TopicOf {};
#define IGNAV_TOPIC_OF(Type, name_, qos_)      \
  template <>                                  \
  struct TopicOf<Type> {                       \
    static constexpr const char* name = name_; \
    static constexpr Qos qos = qos_;           \
  }

}  // namespace ignav::protocol
