#include "ignav/core/expected.hpp"

namespace ignav {

const char* toString(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidArgument:
      return "invalid_argument";
    case ErrorCode::kConfig:
      return "config";
    case ErrorCode::kIo:
      return "io";
    case ErrorCode::kFormat:
      return "format";
    case ErrorCode::kUnsupported:
      return "unsupported";
    case ErrorCode::kDegenerate:
      return "degenerate";
    case ErrorCode::kInternal:
      return "internal";
  }
  return "internal";
}

}  // namespace ignav
