// Between the generated C types and the workflow's values. The C types point into memory they
// do not own: the Owned* holders keep that memory alive while a sample is written.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "ignav/protocol/dds.hpp"
#include "ignav/workflow/session.hpp"

namespace ignav::protocol {

inline char* cstr(const std::string& s) {
  return const_cast<char*>(s.c_str());
}
// Never of a temporary: the sample would point into a string that is gone before it is written
// (ASan found one; docs/RELIABILITY.md).
char* cstr(std::string&& s) = delete;

template <typename Seq, typename T>
void viewSequence(Seq& seq, std::vector<T>& items) {
  seq._maximum = seq._length = static_cast<std::uint32_t>(items.size());
  seq._buffer = items.empty() ? nullptr : items.data();
  seq._release = false;
}

inline ignav_msg_Point3 toMsg(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}
inline Eigen::Vector3d fromMsg(const ignav_msg_Point3& p) {
  return {p.x, p.y, p.z};
}

template <typename Points>
std::vector<ignav_msg_Point3> toMsgs(const Points& points) {
  std::vector<ignav_msg_Point3> out;
  for (const auto& p : points)
    out.push_back(toMsg(p));
  return out;
}

// 4x4 matrices travel row-major as double[16].
inline void toRowMajor(const Eigen::Matrix4d& m, double (&out)[16]) {
  for (int i = 0; i < 16; ++i)
    out[i] = m(i / 4, i % 4);
}
inline Eigen::Matrix4d fromRowMajor(const double (&in)[16]) {
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i)
    m(i / 4, i % 4) = in[i];
  return m;
}

// Command.kind of a command by name ("load_volume", ...; workflow/inputs.hpp), for clients;
// nullopt for a name that is no command on the Command topics (approve has its own topic).
std::optional<std::int32_t> commandKindFromName(const std::string& name);
// Command.kind is an integer on the wire, so these take any value ("unknown" / approver for a
// value no command has).
const char* commandKindName(std::int32_t kind);
// The least role that may give a command: it travels on commandTopic(requiredRole(kind)).
Role requiredRole(std::int32_t kind);

// A command as the workflow sees it; nullopt when the kind is not one of ours.
std::optional<workflow::Input> toInput(const ignav_msg_Command& command);
workflow::Input toInput(const ignav_msg_Approval& approval);
workflow::Input toInput(const ignav_msg_EmergencyStop& stop);

struct OwnedCommand {
  std::string client_id, path;
  std::vector<ignav_msg_Point3> points;
  std::vector<std::uint32_t> ids;
  std::array<double, 16> matrix{};  // row-major
  ignav_msg_Command msg{};
  const ignav_msg_Command& build(std::uint64_t request_id, std::int32_t kind);  // Command.kind
};

struct OwnedReply {
  workflow::Reply reply;
  ignav_msg_Reply msg{};
  const ignav_msg_Reply& build();
};

// A reply as a client sees it (strings copied out of the loaned sample).
workflow::Reply fromMsg(const ignav_msg_Reply& msg);

}  // namespace ignav::protocol
