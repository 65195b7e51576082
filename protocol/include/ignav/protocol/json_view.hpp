// Every value of types.hpp as JSON, from its one list of fields: what `ignavctl status --json`
// and `watch` print and what the web gateway sends browsers (tools/ignav-web/app/src/state.ts
// names the same fields). A point is [x, y, z], a matrix 16 row-major numbers, an absent optional
// null. nlohmann's hooks, so `json j = value;` and `j.get<TargetState>()` work.
//
// Reading JSON back, a field the JSON lacks keeps its default (a server older than the field);
// one of the wrong JSON type throws nlohmann::json::type_error.
#pragma once

#include <nlohmann/json.hpp>

#include "ignav/protocol/types.hpp"

namespace ignav::protocol {

void to_json(nlohmann::json& j, const Point3& value);
void from_json(const nlohmann::json& j, Point3& value);

#define IGNAV_PROTOCOL_JSON_VIEW(Type)                \
  void to_json(nlohmann::json& j, const Type& value); \
  void from_json(const nlohmann::json& j, Type& value)
IGNAV_PROTOCOL_JSON_VIEW(Command);
IGNAV_PROTOCOL_JSON_VIEW(Reply);
IGNAV_PROTOCOL_JSON_VIEW(Approval);
IGNAV_PROTOCOL_JSON_VIEW(EmergencyStop);
IGNAV_PROTOCOL_JSON_VIEW(SliceRequest);
IGNAV_PROTOCOL_JSON_VIEW(WorkflowState);
IGNAV_PROTOCOL_JSON_VIEW(RobotState);
IGNAV_PROTOCOL_JSON_VIEW(VolumeState);
IGNAV_PROTOCOL_JSON_VIEW(RegistrationState);
IGNAV_PROTOCOL_JSON_VIEW(TargetState);
IGNAV_PROTOCOL_JSON_VIEW(PlannedMove);
IGNAV_PROTOCOL_JSON_VIEW(ApprovalState);
IGNAV_PROTOCOL_JSON_VIEW(MotionState);
IGNAV_PROTOCOL_JSON_VIEW(Health);
IGNAV_PROTOCOL_JSON_VIEW(JobOutcome);
IGNAV_PROTOCOL_JSON_VIEW(ErrorStats);
IGNAV_PROTOCOL_JSON_VIEW(SeedState);
IGNAV_PROTOCOL_JSON_VIEW(MeasuredTargetState);
IGNAV_PROTOCOL_JSON_VIEW(FittedTissueState);
IGNAV_PROTOCOL_JSON_VIEW(VerificationState);
IGNAV_PROTOCOL_JSON_VIEW(ClearanceState);
IGNAV_PROTOCOL_JSON_VIEW(StructureInfo);
IGNAV_PROTOCOL_JSON_VIEW(ProposedTargetInfo);
IGNAV_PROTOCOL_JSON_VIEW(PlacementInfo);
IGNAV_PROTOCOL_JSON_VIEW(DoseMetricsInfo);
IGNAV_PROTOCOL_JSON_VIEW(StructuresState);
#undef IGNAV_PROTOCOL_JSON_VIEW

}  // namespace ignav::protocol
