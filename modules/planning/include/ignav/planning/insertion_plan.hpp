// One insertion's motion plan: the order of the targets and, per target, the joint moves the
// mechanism makes (retract stylet, translate cannula, rotate cannula, deploy stylet), each as
// motor steps through the transmission. Pure: values in, values out.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "ignav/actuation/transmission.hpp"
#include "ignav/core/expected.hpp"
#include "ignav/kinematics/solver.hpp"

namespace ignav::planning {

// Trapezoidal profile per axis, in joint units.
struct AxisProfile {
  double speed = 1.0;         // deg/s for θc, mm/s for zc and zs
  double acceleration = 4.0;  // deg/s², mm/s²
};

struct PlanningLimits {
  std::size_t max_targets = 100;             // per insertion (paper §V)
  double max_total_rotation_rad = 2 * M_PI;  // the paper's rule, to limit backlash
  AxisProfile theta_c{30.0, 120.0};
  AxisProfile z_c{2.0, 8.0};
  AxisProfile z_s{2.0, 8.0};
};

struct PlannedTarget {
  std::uint32_t id = 0;
  kinematics::Joints joints;  // exact IK of the target
};

enum class MoveKind { kRetractStylet, kTranslateCannula, kRotateCannula, kDeployStylet };
const char* toString(MoveKind kind);

struct JointMove {
  MoveKind kind = MoveKind::kRetractStylet;
  kinematics::Joints from, to;
  actuation::Steps steps;  // increments per motor
  double duration_s = 0.0;
};

struct TargetMotion {
  std::uint32_t target_id = 0;
  std::vector<JointMove> moves;  // moves with nothing to do are left out
  double duration_s = 0.0;
};

struct InsertionPlan {
  std::vector<std::uint32_t> order;  // target ids
  std::vector<TargetMotion> motions;
  JointMove final_retract;  // stylet home after the last target
  double total_rotation_rad = 0.0;
  double duration_s = 0.0;
};

// Time for one axis to travel `distance` (joint units) from rest to rest.
double moveDuration_s(double distance, const AxisProfile& axis);

// The order of the targets as visited from `start`, with its rotation and time; no steps.
struct Ordering {
  std::vector<std::size_t> order;  // indices into the targets
  double total_rotation_rad = 0.0;
  double duration_s = 0.0;
};
Ordering evaluateOrder(const std::vector<PlannedTarget>& targets,
                       const std::vector<std::size_t>& order, const kinematics::Joints& start,
                       const PlanningLimits& limits);

// Orders the targets so that the total cannula rotation stays within the limit and, among
// such orders, the motion time is least: every order for up to 8 targets; beyond that the
// monotone sweep in θc (whose rotation is the span of the θc values, < 360° from home) in both
// senses, improved by 2-opt and or-opt moves that keep the rotation within the limit (a local
// optimum; tests measure it against brute force at 9 targets).
Ordering orderTargets(const std::vector<PlannedTarget>& targets, const kinematics::Joints& start,
                      const PlanningLimits& limits);

// The whole plan. Errors: no targets, more than max_targets, duplicate ids, a pose outside the
// joint ranges (named), or non-positive speeds.
Expected<InsertionPlan> planInsertion(const kinematics::Kinematics& kinematics,
                                      const actuation::Transmission& transmission,
                                      const std::vector<PlannedTarget>& targets,
                                      const kinematics::Joints& start,
                                      const PlanningLimits& limits);

}  // namespace ignav::planning
