// Between the C types idlc generates and C++ values. A wire header (like dds.hpp): protocol/, the
// server, and tests and fuzzers that build raw samples.
//
// Each topic with a value type (types.hpp) converts by that value's one list of fields:
//   Owned<ignav_msg_TargetState> owned;  writer.write(toMsg(target, owned));
//   TargetState t = fromMsg(sample);
// and TopicWriter<T> / TopicReader<T> do that around a Writer / Reader of T's topic. Commands and
// replies too (what the workflow takes of them is the server's: server/requests.hpp).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <type_traits>
#include <vector>

#include "ignav/protocol/commands.hpp"
#include "ignav/protocol/types.hpp"
#include "ignav/protocol/wire/dds.hpp"

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

// ---- values by their field lists -----------------------------------------------------------

// The C type of each value type, and back.
template <typename T>
struct MsgOf {};
template <typename Msg>
struct ValueOf {};
#define IGNAV_PROTOCOL_MSG(Type, Msg)                                         \
  template <>                                                                 \
  struct MsgOf<Type> {                                                        \
    using type = Msg;                                                         \
    static const dds_topic_descriptor_t* descriptor() { return &Msg##_desc; } \
  };                                                                          \
  template <>                                                                 \
  struct ValueOf<Msg> {                                                       \
    using type = Type;                                                        \
  }
IGNAV_PROTOCOL_MSG(Command, ignav_msg_Command);
IGNAV_PROTOCOL_MSG(Reply, ignav_msg_Reply);
IGNAV_PROTOCOL_MSG(Approval, ignav_msg_Approval);
IGNAV_PROTOCOL_MSG(EmergencyStop, ignav_msg_EmergencyStop);
IGNAV_PROTOCOL_MSG(SliceRequest, ignav_msg_SliceRequest);
IGNAV_PROTOCOL_MSG(SliceReply, ignav_msg_SliceReply);
IGNAV_PROTOCOL_MSG(SceneRequest, ignav_msg_SceneRequest);
IGNAV_PROTOCOL_MSG(SceneSurface, ignav_msg_SceneSurface);
IGNAV_PROTOCOL_MSG(SceneReply, ignav_msg_SceneReply);
IGNAV_PROTOCOL_MSG(WorkflowState, ignav_msg_WorkflowState);
IGNAV_PROTOCOL_MSG(RobotState, ignav_msg_RobotState);
IGNAV_PROTOCOL_MSG(VolumeState, ignav_msg_VolumeState);
IGNAV_PROTOCOL_MSG(RegistrationState, ignav_msg_RegistrationState);
IGNAV_PROTOCOL_MSG(ClearanceState, ignav_msg_ClearanceState);
IGNAV_PROTOCOL_MSG(TargetState, ignav_msg_TargetState);
IGNAV_PROTOCOL_MSG(StructureInfo, ignav_msg_StructureInfo);
IGNAV_PROTOCOL_MSG(ProposedTargetInfo, ignav_msg_ProposedTargetInfo);
IGNAV_PROTOCOL_MSG(PlacementInfo, ignav_msg_PlacementInfo);
IGNAV_PROTOCOL_MSG(DoseMetricsInfo, ignav_msg_DoseMetricsInfo);
IGNAV_PROTOCOL_MSG(StructuresState, ignav_msg_StructuresState);
IGNAV_PROTOCOL_MSG(PlannedMove, ignav_msg_PlannedMove);
IGNAV_PROTOCOL_MSG(ApprovalState, ignav_msg_ApprovalState);
IGNAV_PROTOCOL_MSG(MotionState, ignav_msg_MotionState);
IGNAV_PROTOCOL_MSG(Health, ignav_msg_Health);
IGNAV_PROTOCOL_MSG(JobOutcome, ignav_msg_JobOutcome);
IGNAV_PROTOCOL_MSG(ErrorStats, ignav_msg_ErrorStats);
IGNAV_PROTOCOL_MSG(SeedState, ignav_msg_SeedState);
IGNAV_PROTOCOL_MSG(MeasuredTargetState, ignav_msg_MeasuredTargetState);
IGNAV_PROTOCOL_MSG(FittedTissueState, ignav_msg_FittedTissueState);
IGNAV_PROTOCOL_MSG(VerificationState, ignav_msg_VerificationState);
#undef IGNAV_PROTOCOL_MSG

// A sample written from a value points into the value (strings, byte and number sequences) and
// into the buffers kept here (sequences of structs and strings): keep both until it is written.
template <typename Msg>
class Owned {
 public:
  Msg msg{};
  template <typename E>
  E* buffer(std::size_t n) {
    auto held = std::make_shared<std::vector<E>>(n);
    held_.push_back(held);
    return held->data();
  }

 private:
  std::vector<std::shared_ptr<void>> held_;
};

namespace wire_detail {

// Each kind of member to and from its C form; a struct with a field list field by field. Members
// of one struct, so that each overload sees all the others.
struct Convert {
  // ---- value -> C ----
  template <typename Msg>
  static void put(const std::string& v, char*& c, Owned<Msg>&) {
    c = cstr(v);
  }
  template <typename A, typename Msg>
  static std::enable_if_t<std::is_arithmetic_v<A>> put(const A& v, A& c, Owned<Msg>&) {
    c = v;
  }
  template <typename Msg>
  static void put(const Point3& v, ignav_msg_Point3& c, Owned<Msg>&) {
    c = {v.x, v.y, v.z};
  }
  template <typename T, std::size_t N, typename C, typename Msg>
  static void put(const std::array<T, N>& v, C (&c)[N], Owned<Msg>& o) {
    for (std::size_t i = 0; i < N; ++i)
      put(v[i], c[i], o);
  }
  template <typename T, std::size_t N, typename... C, typename Msg>
  static void put(const std::array<T, N>& v, std::tuple<C&...> c, Owned<Msg>& o) {
    static_assert(sizeof...(C) == N, "one C member per element");
    putEach(v, c, o, std::make_index_sequence<N>());
  }
  template <typename T, typename C, typename Msg>
  static void put(const std::optional<T>& v, std::tuple<C&, bool&> c, Owned<Msg>& o) {
    std::get<1>(c) = v.has_value();
    if (v) {
      put(*v, std::get<0>(c), o);
    } else {
      std::get<0>(c) = C{};
    }
  }
  template <typename T, typename Seq, typename Msg>
  static auto put(const std::vector<T>& v, Seq& seq, Owned<Msg>& o)
      -> decltype(seq._buffer, void()) {
    using E = std::remove_pointer_t<decltype(seq._buffer)>;
    seq._maximum = seq._length = static_cast<std::uint32_t>(v.size());
    seq._release = false;
    if (v.empty()) {
      seq._buffer = nullptr;
    } else if constexpr (std::is_same_v<T, E> && std::is_arithmetic_v<T>) {
      seq._buffer = const_cast<E*>(v.data());  // numbers and bytes: lent, not copied
    } else {
      seq._buffer = o.template buffer<E>(v.size());
      for (std::size_t i = 0; i < v.size(); ++i)
        put(v[i], seq._buffer[i], o);
    }
  }
  template <typename T, typename C, typename Msg>
  static std::enable_if_t<HasFields<T>::value> put(const T& v, C& c, Owned<Msg>& o) {
    forEachField<T>([&](const auto& f) { put(v.*f.member, f.wire(c), o); });
  }
  template <typename T, std::size_t N, typename Tuple, typename Msg, std::size_t... I>
  static void putEach(const std::array<T, N>& v, Tuple c, Owned<Msg>& o,
                      std::index_sequence<I...>) {
    (put(v[I], std::get<I>(c), o), ...);
  }

  // ---- C -> value ----
  static void get(const char* c, std::string& v) { v = c ? c : ""; }
  template <typename A>
  static std::enable_if_t<std::is_arithmetic_v<A>> get(const A& c, A& v) {
    v = c;
  }
  static void get(const ignav_msg_Point3& c, Point3& v) { v = {c.x, c.y, c.z}; }
  template <typename C, typename T, std::size_t N>
  static void get(const C (&c)[N], std::array<T, N>& v) {
    for (std::size_t i = 0; i < N; ++i)
      get(c[i], v[i]);
  }
  template <typename... C, typename T, std::size_t N>
  static void get(std::tuple<const C&...> c, std::array<T, N>& v) {
    static_assert(sizeof...(C) == N, "one C member per element");
    getEach(c, v, std::make_index_sequence<N>());
  }
  template <typename C, typename T>
  static void get(std::tuple<const C&, const bool&> c, std::optional<T>& v) {
    if (!std::get<1>(c)) {
      v.reset();
      return;
    }
    T value{};
    get(std::get<0>(c), value);
    v = std::move(value);
  }
  template <typename Seq, typename T>
  static auto get(const Seq& seq, std::vector<T>& v) -> decltype(seq._buffer, void()) {
    v.assign(seq._length, T{});
    for (std::uint32_t i = 0; i < seq._length; ++i)
      get(seq._buffer[i], v[i]);
  }
  template <typename C, typename T>
  static std::enable_if_t<HasFields<T>::value> get(const C& c, T& v) {
    forEachField<T>([&](const auto& f) { get(f.wire(c), v.*f.member); });
  }
  template <typename Tuple, typename T, std::size_t N, std::size_t... I>
  static void getEach(Tuple c, std::array<T, N>& v, std::index_sequence<I...>) {
    (get(std::get<I>(c), v[I]), ...);
  }
};

}  // namespace wire_detail

// The sample of `value`, in `owned` (see Owned: `value` must outlive the write).
template <typename T>
const typename MsgOf<T>::type& toMsg(const T& value, Owned<typename MsgOf<T>::type>& owned) {
  owned.msg = {};
  wire_detail::Convert::put(value, owned.msg, owned);
  return owned.msg;
}
template <typename T>
void toMsg(const T&& value, Owned<typename MsgOf<T>::type>& owned) = delete;

// The value of a taken sample (everything copied out of it).
template <typename Msg>
typename ValueOf<Msg>::type fromMsg(const Msg& msg) {
  typename ValueOf<Msg>::type value;
  wire_detail::Convert::get(msg, value);
  return value;
}

// A writer of T's topic (TopicOf<T>) that takes values.
template <typename T>
class TopicWriter {
 public:
  using Msg = typename MsgOf<T>::type;
  explicit TopicWriter(const Participant& p)
      : writer_(p, MsgOf<T>::descriptor(), TopicOf<T>::name, TopicOf<T>::qos) {}
  void write(const T& value) const {
    Owned<Msg> owned;
    writer_.write(toMsg(value, owned));
  }
  // Only the key fields matter.
  void dispose(const T& value) const {
    Owned<Msg> owned;
    writer_.dispose(toMsg(value, owned));
  }
  std::size_t matched() const { return writer_.matched(); }
  dds_entity_t handle() const { return writer_.handle(); }

 private:
  Writer<Msg> writer_;
};

// A reader of T's topic (TopicOf<T>) that gives values.
template <typename T>
class TopicReader {
 public:
  using Msg = typename MsgOf<T>::type;
  explicit TopicReader(const Participant& p, Qos qos = TopicOf<T>::qos)
      : reader_(p, MsgOf<T>::descriptor(), TopicOf<T>::name, qos) {}
  // Only the samples `keep(sample, arg)` accepts (Reader's filter; `arg` outlives the reader).
  TopicReader(const Participant& p, dds_topic_filter_arg_fn keep, void* arg)
      : reader_(p, MsgOf<T>::descriptor(), TopicOf<T>::name, TopicOf<T>::qos, keep, arg) {}
  std::size_t take(const std::function<void(const T&)>& fn) const {
    return reader_.take([&](const Msg& m) { fn(fromMsg(m)); });
  }
  // Data to `data`, a disposal to `disposed` as the sample it came as: only its key fields are
  // set, so only they may be read.
  std::size_t takeWithState(const std::function<void(const T&)>& data,
                            const std::function<void(const Msg&)>& disposed) const {
    return reader_.takeWithState([&](const Msg& m, bool alive) {
      if (alive) {
        data(fromMsg(m));
      } else {
        disposed(m);
      }
    });
  }
  std::size_t matched() const { return reader_.matched(); }
  dds_entity_t handle() const { return reader_.handle(); }

 private:
  Reader<Msg> reader_;
};

// ---- commands and replies ------------------------------------------------------------------

// The command of a taken sample by its field list, with at most kMaxCommandItemsRead points and
// ids copied out (the workflow judges the rest: an oversized command is refused by name).
Command commandOf(const ignav_msg_Command& sample);

}  // namespace ignav::protocol
