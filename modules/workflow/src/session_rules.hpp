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
// After the registration changed: with a robot placement proposed, measure the robot where it now
// stands against it (a placement check job); without a registration, forget the last check.
void checkMountedRobot(Session& s, Effects& e);

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

// The landing of `joints` in `model`, uncertain by `fit`'s covariance of λ1, λ2: √trace(J Σ Jᵀ),
// J by central differences (needle_scan.cpp). Infinite where the model cannot say (a perturbed λ
// inadmissible).
double landingSe_mm(const kinematics::Kinematics& kin, const compensation::DeflectionModel& model,
                    const compensation::TargetingFit& fit, const kinematics::Joints& joints);

// The whole needle of `t` (its commanded joints) against every avoided structure
// (clearance_rules.cpp): t.clearances and, when one is too close, t.clearance_refusal.
void checkClearance(const Session& s, Target& t);

// A scan's registration given with its command (load_confirmation, scan_needle), checked as
// set_registration checks one, before any work: why not ("`what`: ..."), or nullopt.
std::optional<Rejection> checkGivenMatrix(const Session& s,
                                          const std::optional<Eigen::Matrix4d>& matrix,
                                          const std::string& what);
// A confirmation or intermittent CT registered: by the transform given with it, else its markers
// (`markers_lps_mm`, in the model's order) compared with the session's registration.
Expected<verification::ConfirmationRegistration> registerScan(
    const config::Robot& robot, const std::optional<registration::Registration>& session,
    const std::vector<Eigen::Vector3d>& markers_lps_mm,
    const std::optional<Eigen::Matrix4d>& given);

// The insertion under way when it stopped part-way (pause_at): the first target not reached, in
// plan order, if it is paused; else none.
const Target* pausedInsertion(const Session& s);
Target* pausedInsertion(Session& s);

// The confirmation CT's measured rows as a tissue fit takes them (robot frame; a tip's needle
// path with it). Empty without a measured scan.
std::vector<compensation::TargetingRecord> measuredRecords(const Session& s);

}  // namespace ignav::workflow::detail
