// The rules the transition rows' actions share (session_rules.cpp): targets judged against the CT
// and the registration, registrations adopted, marker detections' outcomes, the approval policy.
// Internal to modules/workflow; pure.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "ignav/workflow/session.hpp"
#include "motion.hpp"

namespace ignav::workflow::detail {

// modules/registration names its reasons; each is one of the reply codes (a test checks them).
Rejection registrationRefusal(const Error& error);

Target* findTarget(Session& s, std::uint32_t id);

// A point to target must lie in tissue the loaded CT shows (issue 26: a CT whose field of view
// cuts the workspace left reachable targets in tissue nobody had seen). Without a CT here (the
// registration came from 3D Slicer, which holds the images) there is nothing to check against.
std::optional<Rejection> checkInsideCt(const Session& s, const Eigen::Vector3d& lps_mm);

// Derives everything about `t` from its LPS point, the CT, the registration and the robot
// (reachability, joints, steps, expected TRE, path warnings, predicted drift); where the needle
// has been (reached) stays.
void evaluate(const Session& s, Target& t);
void evaluateAll(Session& s, Effects& e);

// The registration of the robot's feature points onto `image` (in their order), or why none.
Expected<registration::Registration> registerOnRobot(const config::Robot& robot,
                                                     const std::vector<Eigen::Vector3d>& image);
// registerOnRobot() into the session, every target evaluated again.
std::optional<Rejection> adoptRegistration(Session& s, const std::vector<Eigen::Vector3d>& image,
                                           bool auto_detected, Effects& e);

// A marker detection's outcome that registered nothing: a registration from before stays in use.
void detectionFailed(Session& s, const std::string& why, Effects& e);
// A registration given by hand (or by matrix) while the markers were being detected: the
// detection's result will be ignored. The note for the reply.
std::string dropDetection(Session& s);
// Why a detection's outcome is not the one the session awaits (Session::detecting).
std::string staleDetection(const Session& s, const Input& in);

void adoptPolicy(Session& s, ApprovalPolicy policy);

// The confirmation CT's measured rows as a tissue fit takes them (robot frame; a tip's needle
// path with it). Empty without a measured scan.
std::vector<compensation::TargetingRecord> measuredRecords(const Session& s);

}  // namespace ignav::workflow::detail
