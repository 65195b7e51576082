// How a topic's fields are listed once (types.hpp) and walked by everything that needs them: the
// JSON view (json_view.hpp) and the conversions to and from the C types idlc generates
// (wire/messages.hpp). No DDS and no generated code here: a field's place in the C type is an
// accessor that is only instantiated by the wire layer.
#pragma once

#include <tuple>
#include <type_traits>

namespace ignav::protocol {

// One field of a value type T: its name in the JSON view, its member, and `wire(sample)`, which
// gives the C member it travels in (a reference) or the several it travels in as one (a std::tie:
// three joints, or an optional value and its flag).
template <typename T, typename M, typename Wire>
struct Field {
  const char* name;
  M T::*member;
  Wire wire;
};

template <typename T, typename M, typename Wire>
constexpr Field<T, M, Wire> field(const char* name, M T::*member, Wire wire) {
  return {name, member, wire};
}

// Specialised for each value type: `static constexpr auto list = std::make_tuple(field(...),
// ...)`, in the order of the IDL.
template <typename T>
struct Fields {};

template <typename T, typename = void>
struct HasFields : std::false_type {};
template <typename T>
struct HasFields<T, std::void_t<decltype(Fields<T>::list)>> : std::true_type {};

// f(field) for each field of T, in order.
template <typename T, typename F>
constexpr void forEachField(F&& f) {
  std::apply([&](const auto&... each) { (f(each), ...); }, Fields<T>::list);
}

}  // namespace ignav::protocol

// The common field: the same name in the value type, the JSON view and the C type. Used inside a
// Fields<T> specialisation that declares `using T = ...`.
#define IGNAV_FIELD(member) \
  ::ignav::protocol::field( \
      #member, &T::member, [](auto& msg) -> auto& { return msg.member; })
