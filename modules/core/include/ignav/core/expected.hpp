// Expected<T>: a value or an Error that says what went wrong, for C++17 (no std::expected).
// Modules return these instead of throwing across their boundary.
#pragma once

#include <string>
#include <utility>
#include <variant>

namespace ignav {

// What kind of failure, so a caller (and the DDS reply) can branch on it; the message is for a
// person and names the field, value and limit.
enum class ErrorCode {
  kInvalidArgument,  // a value out of range, NaN, wrong size
  kConfig,           // a configuration file or key is wrong
  kIo,               // a file could not be read or written
  kFormat,           // a file was read but its content is malformed
  kUnsupported,      // valid input we deliberately do not handle (named in the message)
  kDegenerate,       // geometry that has no unique answer (collinear points, ...)
  kInternal,         // a bug: an invariant of ours did not hold
};

const char* toString(ErrorCode code);

struct Error {
  ErrorCode code = ErrorCode::kInternal;
  std::string message;
  // A short machine-readable token finer than `code` (e.g. "collinear"), for replies that a
  // client branches on; empty when the code says enough.
  std::string reason;
};

template <typename T>
class Expected {
 public:
  Expected(T value) : storage_(std::move(value)) {}      // NOLINT: implicit by design
  Expected(Error error) : storage_(std::move(error)) {}  // NOLINT: implicit by design

  bool ok() const { return std::holds_alternative<T>(storage_); }
  explicit operator bool() const { return ok(); }

  const T& value() const& { return std::get<T>(storage_); }
  T& value() & { return std::get<T>(storage_); }
  T&& value() && { return std::get<T>(std::move(storage_)); }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }

  const Error& error() const { return std::get<Error>(storage_); }

 private:
  std::variant<T, Error> storage_;
};

// For operations that return nothing but can fail.
struct Ok {};
using Status = Expected<Ok>;

inline Error makeError(ErrorCode code, std::string message, std::string reason = {}) {
  return Error{code, std::move(message), std::move(reason)};
}

}  // namespace ignav
