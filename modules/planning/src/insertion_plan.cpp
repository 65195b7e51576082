#include "ignav/planning/insertion_plan.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>

#include <fmt/format.h>

namespace ignav::planning {
namespace {

using kinematics::Joints;

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr std::size_t kExhaustiveTargets = 8;

// Seconds for each order-dependent and fixed leg, from pose `from` to target pose `to`.
double legDuration_s(const Joints& from, const Joints& to, const PlanningLimits& l) {
  return moveDuration_s(from.z_s_mm, l.z_s) +                        // retract
         moveDuration_s(std::abs(to.z_c_mm - from.z_c_mm), l.z_c) +  // translate
         moveDuration_s(std::abs(to.theta_c_rad - from.theta_c_rad) * kRadToDeg, l.theta_c) +
         moveDuration_s(to.z_s_mm, l.z_s);  // deploy
}

Status checkProfile(const AxisProfile& a, const char* name) {
  if (!(a.speed > 0.0) || !(a.acceleration > 0.0) || !std::isfinite(a.speed) ||
      !std::isfinite(a.acceleration)) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{}: speed {:g} and acceleration {:g} must be positive", name,
                                 a.speed, a.acceleration));
  }
  return Ok{};
}

}  // namespace

const char* toString(MoveKind kind) {
  switch (kind) {
    case MoveKind::kRetractStylet:
      return "retract_stylet";
    case MoveKind::kTranslateCannula:
      return "translate_cannula";
    case MoveKind::kRotateCannula:
      return "rotate_cannula";
    case MoveKind::kDeployStylet:
      return "deploy_stylet";
  }
  return "unknown";
}

double moveDuration_s(double distance, const AxisProfile& axis) {
  distance = std::abs(distance);
  if (distance == 0.0) return 0.0;
  // Accelerate to speed, cruise, decelerate; a short move never reaches speed (triangle).
  const double ramp = axis.speed * axis.speed / axis.acceleration;  // distance of both ramps
  if (distance >= ramp) return distance / axis.speed + axis.speed / axis.acceleration;
  return 2.0 * std::sqrt(distance / axis.acceleration);
}

Ordering evaluateOrder(const std::vector<PlannedTarget>& targets,
                       const std::vector<std::size_t>& order, const Joints& start,
                       const PlanningLimits& limits) {
  Ordering o;
  o.order = order;
  Joints at = start;
  for (std::size_t i : order) {
    const Joints& to = targets[i].joints;
    o.total_rotation_rad += std::abs(to.theta_c_rad - at.theta_c_rad);
    o.duration_s += legDuration_s(at, to, limits);
    at = to;
  }
  o.duration_s += moveDuration_s(at.z_s_mm, limits.z_s);  // final retract
  return o;
}

namespace {

bool feasible(const Ordering& o, const PlanningLimits& limits) {
  return o.total_rotation_rad <= limits.max_total_rotation_rad + 1e-12;
}

// Is a better than b: feasible first, then faster (or, both infeasible, less rotation).
bool better(const Ordering& a, const Ordering& b, const PlanningLimits& limits) {
  if (feasible(a, limits) != feasible(b, limits)) return feasible(a, limits);
  if (!feasible(a, limits)) return a.total_rotation_rad < b.total_rotation_rad;
  return a.duration_s < b.duration_s - 1e-12;
}

// 2-opt (reverse a segment) and or-opt (move one target elsewhere) until neither helps.
Ordering improve(Ordering best, const std::vector<PlannedTarget>& targets, const Joints& start,
                 const PlanningLimits& limits) {
  const std::size_t n = best.order.size();
  for (int pass = 0; pass < 50; ++pass) {
    bool improved = false;
    for (std::size_t i = 0; i + 1 < n; ++i) {
      for (std::size_t j = i + 1; j < n; ++j) {
        auto order = best.order;
        std::reverse(order.begin() + static_cast<std::ptrdiff_t>(i),
                     order.begin() + static_cast<std::ptrdiff_t>(j) + 1);
        if (auto c = evaluateOrder(targets, order, start, limits); better(c, best, limits)) {
          best = std::move(c);
          improved = true;
        }
      }
    }
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = 0; j < n; ++j) {
        if (i == j) continue;
        auto order = best.order;
        const std::size_t moved = order[i];
        order.erase(order.begin() + static_cast<std::ptrdiff_t>(i));
        order.insert(order.begin() + static_cast<std::ptrdiff_t>(j), moved);
        if (auto c = evaluateOrder(targets, order, start, limits); better(c, best, limits)) {
          best = std::move(c);
          improved = true;
        }
      }
    }
    if (!improved) break;
  }
  return best;
}

}  // namespace

Ordering orderTargets(const std::vector<PlannedTarget>& targets, const Joints& start,
                      const PlanningLimits& limits) {
  const std::size_t n = targets.size();
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  if (n <= kExhaustiveTargets) {  // 8! = 40320 orders: try them all
    Ordering best = evaluateOrder(targets, order, start, limits);
    while (std::next_permutation(order.begin(), order.end())) {
      if (auto c = evaluateOrder(targets, order, start, limits); better(c, best, limits)) {
        best = std::move(c);
      }
    }
    return best;
  }
  // Larger plans: local search from the θc sweep in both senses; the sweep's rotation is the
  // span of the θc values, so a feasible start exists whenever one is possible from home.
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const auto& ja = targets[a].joints;
    const auto& jb = targets[b].joints;
    return std::tie(ja.theta_c_rad, ja.z_c_mm) < std::tie(jb.theta_c_rad, jb.z_c_mm);
  });
  Ordering best = improve(evaluateOrder(targets, order, start, limits), targets, start, limits);
  std::reverse(order.begin(), order.end());
  Ordering down = improve(evaluateOrder(targets, order, start, limits), targets, start, limits);
  return better(down, best, limits) ? down : best;
}

Expected<InsertionPlan> planInsertion(const kinematics::Kinematics& kinematics,
                                      const actuation::Transmission& transmission,
                                      const std::vector<PlannedTarget>& targets,
                                      const Joints& start, const PlanningLimits& limits) {
  if (targets.empty()) return makeError(ErrorCode::kInvalidArgument, "the plan has no targets");
  if (targets.size() > limits.max_targets) {
    return makeError(ErrorCode::kInvalidArgument,
                     fmt::format("{} targets; one insertion takes at most {}", targets.size(),
                                 limits.max_targets));
  }
  for (const auto& [profile, name] :
       {std::pair{&limits.theta_c, "theta_c"}, {&limits.z_c, "z_c"}, {&limits.z_s, "z_s"}}) {
    if (auto ok = checkProfile(*profile, name); !ok) return ok.error();
  }
  if (auto ok = kinematics.checkJoints(start); !ok) {
    return makeError(ErrorCode::kInvalidArgument, "start pose: " + ok.error().message);
  }
  std::set<std::uint32_t> ids;
  for (const auto& t : targets) {
    if (!ids.insert(t.id).second) {
      return makeError(ErrorCode::kInvalidArgument, fmt::format("target {} appears twice", t.id));
    }
    if (auto ok = kinematics.checkJoints(t.joints); !ok) {
      return makeError(ErrorCode::kInvalidArgument,
                       fmt::format("target {}: {}", t.id, ok.error().message));
    }
  }
  const Ordering ordering = orderTargets(targets, start, limits);
  if (ordering.total_rotation_rad > limits.max_total_rotation_rad + 1e-12) {
    return makeError(
        ErrorCode::kDegenerate,
        fmt::format("no order keeps the cannula rotation within {:.1f}°: the best "
                    "needs {:.1f}° from the start at θc = {:.1f}°",
                    limits.max_total_rotation_rad * kRadToDeg,
                    ordering.total_rotation_rad * kRadToDeg, start.theta_c_rad * kRadToDeg),
        "rotation_limit");
  }

  InsertionPlan plan;
  plan.total_rotation_rad = ordering.total_rotation_rad;
  Joints at = start;
  auto moveTo = [&](MoveKind kind, Joints to, std::vector<JointMove>& out) -> Status {
    if (auto ok = kinematics.checkJoints(to); !ok) {  // every intermediate pose
      return makeError(ErrorCode::kInternal, fmt::format("{} leads outside the joint ranges: {}",
                                                         toString(kind), ok.error().message));
    }
    const auto conversion = transmission.move(at, to);
    JointMove m{kind, at, to, conversion.steps, 0.0};
    switch (kind) {
      case MoveKind::kRetractStylet:
      case MoveKind::kDeployStylet:
        m.duration_s = moveDuration_s(to.z_s_mm - at.z_s_mm, limits.z_s);
        break;
      case MoveKind::kTranslateCannula:
        m.duration_s = moveDuration_s(to.z_c_mm - at.z_c_mm, limits.z_c);
        break;
      case MoveKind::kRotateCannula:
        m.duration_s =
            moveDuration_s((to.theta_c_rad - at.theta_c_rad) * kRadToDeg, limits.theta_c);
        break;
    }
    at = to;
    if (m.steps.motor != std::array<std::int64_t, 3>{0, 0, 0} || m.duration_s > 0.0) {
      out.push_back(m);
    }
    return Ok{};
  };
  for (std::size_t i : ordering.order) {
    const auto& target = targets[i];
    TargetMotion motion;
    motion.target_id = target.id;
    Joints pose = at;
    pose.z_s_mm = 0.0;
    if (auto s = moveTo(MoveKind::kRetractStylet, pose, motion.moves); !s) return s.error();
    pose.z_c_mm = target.joints.z_c_mm;
    if (auto s = moveTo(MoveKind::kTranslateCannula, pose, motion.moves); !s) return s.error();
    pose.theta_c_rad = target.joints.theta_c_rad;
    if (auto s = moveTo(MoveKind::kRotateCannula, pose, motion.moves); !s) return s.error();
    pose.z_s_mm = target.joints.z_s_mm;
    if (auto s = moveTo(MoveKind::kDeployStylet, pose, motion.moves); !s) return s.error();
    for (const auto& m : motion.moves)
      motion.duration_s += m.duration_s;
    plan.duration_s += motion.duration_s;
    plan.order.push_back(target.id);
    plan.motions.push_back(std::move(motion));
  }
  Joints home = at;
  home.z_s_mm = 0.0;
  std::vector<JointMove> last;
  if (auto s = moveTo(MoveKind::kRetractStylet, home, last); !s) return s.error();
  if (!last.empty()) {
    plan.final_retract = last.front();
    plan.duration_s += last.front().duration_s;
  }
  return plan;
}

}  // namespace ignav::planning
