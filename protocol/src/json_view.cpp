#include "ignav/protocol/json_view.hpp"

#include <type_traits>

namespace ignav::protocol {
namespace {

using nlohmann::json;

// The JSON of each kind of member; a struct with a field list is an object of its fields.
// Members of one struct, so that each overload sees all the others.
struct Json {
  static json put(const std::string& v) { return v; }
  template <typename A>
  static std::enable_if_t<std::is_arithmetic_v<A>, json> put(A v) {
    return v;
  }
  static json put(const Point3& p) { return json::array({p.x, p.y, p.z}); }
  template <typename T, std::size_t N>
  static json put(const std::array<T, N>& items) {
    json out = json::array();
    for (const auto& item : items)
      out.push_back(put(item));
    return out;
  }
  template <typename T>
  static json put(const std::vector<T>& items) {
    json out = json::array();
    for (const auto& item : items)
      out.push_back(put(item));
    return out;
  }
  template <typename T>
  static json put(const std::optional<T>& v) {
    return v ? put(*v) : json();
  }
  template <typename T>
  static std::enable_if_t<HasFields<T>::value, json> put(const T& value) {
    json out = json::object();
    forEachField<T>([&](const auto& f) { out[f.name] = put(value.*f.member); });
    return out;
  }

  static void get(const json& j, std::string& v) { v = j.get<std::string>(); }
  template <typename A>
  static std::enable_if_t<std::is_arithmetic_v<A>> get(const json& j, A& v) {
    v = j.get<A>();
  }
  static void get(const json& j, Point3& p) {
    p = {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()};
  }
  template <typename T, std::size_t N>
  static void get(const json& j, std::array<T, N>& items) {
    for (std::size_t i = 0; i < N; ++i)
      get(j.at(i), items[i]);
  }
  template <typename T>
  static void get(const json& j, std::vector<T>& items) {
    const auto& array = j.get_ref<const json::array_t&>();  // throws type_error if not one
    items.assign(array.size(), T{});
    for (std::size_t i = 0; i < array.size(); ++i)
      get(array[i], items[i]);
  }
  template <typename T>
  static void get(const json& j, std::optional<T>& v) {
    if (j.is_null()) {
      v.reset();
      return;
    }
    T value{};
    get(j, value);
    v = std::move(value);
  }
  template <typename T>
  static std::enable_if_t<HasFields<T>::value> get(const json& j, T& value) {
    const auto& object = j.get_ref<const json::object_t&>();  // throws type_error if not one
    forEachField<T>([&](const auto& f) {
      const auto it = object.find(f.name);
      if (it != object.end()) get(it->second, value.*f.member);
    });
  }
};

}  // namespace

void to_json(json& j, const Point3& value) {
  j = Json::put(value);
}
void from_json(const json& j, Point3& value) {
  Json::get(j, value);
}

#define IGNAV_PROTOCOL_JSON_VIEW(Type)         \
  void to_json(json& j, const Type& value) {   \
    j = Json::put(value);                      \
  }                                            \
  void from_json(const json& j, Type& value) { \
    Json::get(j, value);                       \
  }
IGNAV_PROTOCOL_JSON_VIEW(Command)
IGNAV_PROTOCOL_JSON_VIEW(Reply)
IGNAV_PROTOCOL_JSON_VIEW(Approval)
IGNAV_PROTOCOL_JSON_VIEW(EmergencyStop)
IGNAV_PROTOCOL_JSON_VIEW(SliceRequest)
IGNAV_PROTOCOL_JSON_VIEW(WorkflowState)
IGNAV_PROTOCOL_JSON_VIEW(RobotState)
IGNAV_PROTOCOL_JSON_VIEW(VolumeState)
IGNAV_PROTOCOL_JSON_VIEW(RegistrationState)
IGNAV_PROTOCOL_JSON_VIEW(TargetState)
IGNAV_PROTOCOL_JSON_VIEW(PlannedMove)
IGNAV_PROTOCOL_JSON_VIEW(ApprovalState)
IGNAV_PROTOCOL_JSON_VIEW(MotionState)
IGNAV_PROTOCOL_JSON_VIEW(Health)
IGNAV_PROTOCOL_JSON_VIEW(JobOutcome)
IGNAV_PROTOCOL_JSON_VIEW(ErrorStats)
IGNAV_PROTOCOL_JSON_VIEW(SeedState)
IGNAV_PROTOCOL_JSON_VIEW(MeasuredTargetState)
IGNAV_PROTOCOL_JSON_VIEW(FittedTissueState)
IGNAV_PROTOCOL_JSON_VIEW(VerificationState)
IGNAV_PROTOCOL_JSON_VIEW(ClearanceState)
IGNAV_PROTOCOL_JSON_VIEW(StructureInfo)
IGNAV_PROTOCOL_JSON_VIEW(ProposedTargetInfo)
IGNAV_PROTOCOL_JSON_VIEW(PlacementInfo)
IGNAV_PROTOCOL_JSON_VIEW(DoseMetricsInfo)
IGNAV_PROTOCOL_JSON_VIEW(StructuresState)
#undef IGNAV_PROTOCOL_JSON_VIEW

}  // namespace ignav::protocol
