// The ProstateBRP protocol's vocabulary (brp.hpp): workphases and revisions by name, the reply
// codes as STATUS codes and error names, RAS from LPS. The bridge itself is brp.cpp.
#include <set>
#include <utility>

#include "ignav/igtl/brp.hpp"

namespace ignav::igtl {
namespace {

using workflow::Phase;

constexpr Workphase kAllWorkphases[] = {
    Workphase::kStartUp,      Workphase::kPlanning, Workphase::kCalibration, Workphase::kTargeting,
    Workphase::kMoveToTarget, Workphase::kManual,   Workphase::kStop,        Workphase::kEmergency};

// The reply codes longer than the error-name field (19 characters), by a short form of their own.
constexpr std::pair<const char*, const char*> kShortErrorNames[] = {
    {"controller_unavailable", "no_controller"},
};

}  // namespace

const char* toString(Workphase phase) {
  switch (phase) {
    case Workphase::kStartUp:
      return "START_UP";
    case Workphase::kPlanning:
      return "PLANNING";
    case Workphase::kCalibration:
      return "CALIBRATION";
    case Workphase::kTargeting:
      return "TARGETING";
    case Workphase::kMoveToTarget:
      return "MOVE_TO_TARGET";
    case Workphase::kManual:
      return "MANUAL";
    case Workphase::kStop:
      return "STOP";
    case Workphase::kEmergency:
      return "EMERGENCY";
  }
  return "UNKNOWN";
}

const char* toString(Revision revision) {
  return revision == Revision::kBrp2013 ? "brp2013" : "slicer";
}

std::optional<Revision> parseRevision(const std::string& text) {
  if (text == "slicer") return Revision::kSlicer;
  if (text == "brp2013") return Revision::kBrp2013;
  return std::nullopt;
}

std::string errorNameFor(const std::string& error_code) {
  for (const auto& [code, short_name] : kShortErrorNames) {
    if (error_code == code) return short_name;
  }
  return error_code.substr(0, kMaxErrorName);
}

std::optional<Workphase> parseWorkphase(const std::string& text) {
  for (Workphase w : kAllWorkphases) {
    if (text == toString(w)) return w;
  }
  return std::nullopt;
}

Eigen::Matrix4d rasFromLps() {
  return Eigen::Vector4d(-1.0, -1.0, 1.0, 1.0).asDiagonal();
}

StatusCode statusCodeFor(const std::string& error_code, Phase phase, Revision revision) {
  // Values the core refused (as opposed to a robot or workflow that is not ready for them).
  static const std::set<std::string> values = {
      "bad_arguments",       "non_finite",       "out_of_range",
      "oversized",           "too_long",         "not_affine",
      "not_similarity",      "mirror",           "scale_out_of_range",
      "unreachable",         "too_many_targets", "unknown_target",
      "unreachable_targets", "outside_volume"};
  const bool bad_value = values.count(error_code) > 0;
  if (revision == Revision::kBrp2013) {
    // The reference robots know OK, configuration error and not ready, and a hardware failure
    // for a robot that failed on its way.
    if (phase == Phase::kFault) return StatusCode::kHardwareFailure;
    return bad_value ? StatusCode::kConfigurationError : StatusCode::kNotReady;
  }
  if (phase == Phase::kEmergency) return StatusCode::kPanic;
  if (phase == Phase::kManual) return StatusCode::kManualMode;
  static const std::set<std::string> hardware = {"controller_fault", "controller_unavailable",
                                                 "controller_changed"};
  if (phase == Phase::kFault || hardware.count(error_code)) return StatusCode::kHardwareFailure;
  return bad_value ? StatusCode::kConfigurationError : StatusCode::kNotReady;
}

}  // namespace ignav::igtl
