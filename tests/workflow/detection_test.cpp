// auto_fiducials as background work (issue 22): the command starts a marker detection the server
// runs off its event thread; the outcome comes back to the reducer as an input of its own,
// journaled with the image points it registers from. The reducer's side, without DDS or threads:
// the server's detector thread is played by a direct call of detectFiducials().
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <fstream>

#include "ignav/config/robot_config.hpp"
#include "ignav/registration/robot_phantom.hpp"
#include "ignav/volume/phantom.hpp"
#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/reducer.hpp"
#include "support/phantom_ct.hpp"

namespace ignav::workflow {
namespace {

using test::paperRobot;

// The server's job thread, played here: the job a step asked for, made from its session as the
// server makes it (background_jobs.hpp), and run.
Input runStartedJob(const Step& step) {
  EXPECT_EQ(step.effects.start_jobs, std::vector<JobKind>{JobKind::kMarkerDetection});
  auto job = jobKindSpec(JobKind::kMarkerDetection).pending(step.session);
  if (!job) {
    ADD_FAILURE() << "the session awaits no marker detection";
    return {};
  }
  EXPECT_EQ(job->id, step.session.detecting);
  return job->run({});
}

const registration::RobotPhantom& truth() {
  static const registration::RobotPhantom phantom =
      registration::makeRobotPhantom(paperRobot()->kinematics,
                                     paperRobot()->config.registration.scan)
          .value();
  return phantom;
}

// The built-in phantom CT as the server makes it (oblique grid, 8 HU noise; deterministic).
LoadedCt phantomCt() {
  static const auto volume = [] {
    auto spec = truth().spec;
    spec.oblique = true;
    spec.noise_sigma_hu = 8.0;
    return std::make_shared<const volume::Volume>(volume::makePhantom(spec).value());
  }();
  return {volume, "phantom:", "the robot phantom"};
}

// A CT of the same grid with nothing bright in it: no markers to find.
LoadedCt emptyCt() {
  auto spec = truth().spec;
  spec.fiducials_lps_mm.clear();
  return {std::make_shared<const volume::Volume>(volume::makePhantom(spec).value()), "empty.nrrd",
          "no markers"};
}

Input command(InputKind kind, std::uint64_t request, std::vector<Eigen::Vector3d> points = {}) {
  Input in;
  in.kind = kind;
  in.client_id = "test";
  in.request_id = request;
  in.points = std::move(points);
  if (kind == InputKind::kLoadVolume) in.path = "phantom:";
  return in;
}

// The outcome of the CT load `s` awaits.
Input loaded(const Session& s, const LoadedCt& ct) {
  Input in;
  in.kind = InputKind::kVolumeLoaded;
  in.job = s.ct_revision;
  in.loaded = ct;
  return in;
}

// A session in registration with `ct` loaded; its journal in `journal` when given.
Session registrationSession(const LoadedCt& ct, std::vector<std::string>* journal = nullptr) {
  Session s = newSession("t", paperRobot(), "robot.yaml");
  Input config;
  config.kind = InputKind::kConfigLoaded;
  auto feed = [&](const Input& in) {
    auto step = reduce(s, in);
    if (journal)
      journal->insert(journal->end(), step.effects.journal.begin(), step.effects.journal.end());
    s = std::move(step.session);
  };
  feed(config);
  feed(command(InputKind::kLoadVolume, 1));
  feed(loaded(s, ct));
  EXPECT_EQ(s.phase, Phase::kRegistration);
  return s;
}

void expectTrueRegistration(const Session& s) {
  ASSERT_TRUE(s.registration.has_value());
  EXPECT_EQ(s.registration_status.status, "registered");
  EXPECT_TRUE(s.registration_status.auto_detected);
  const Eigen::Matrix4d diff = s.registration->imageToRobot() - truth().image_to_robot_true;
  EXPECT_LT(diff.block(0, 0, 3, 3).norm(), 2e-3);
  EXPECT_LT(diff.block(0, 3, 3, 1).norm(), 0.3);
}

TEST(Detection, AutoFiducialsStartsADetectionAndItsOutcomeRegisters) {
  std::vector<std::string> journal;
  Session s = registrationSession(phantomCt(), &journal);
  auto step = reduce(s, command(InputKind::kAutoFiducials, 2));
  const Reply& reply = step.effects.replies.at(0);
  ASSERT_TRUE(reply.accepted) << reply.message;
  EXPECT_EQ(reply.job, step.session.revision);  // the job it started
  EXPECT_NE(reply.message.find("started"), std::string::npos) << reply.message;
  // Nothing is registered yet: the server is asked to detect, and the state says so.
  EXPECT_EQ(step.session.phase, Phase::kRegistration);
  EXPECT_FALSE(step.session.registration.has_value());
  EXPECT_EQ(step.session.registration_status.status, "detecting");
  EXPECT_TRUE(step.effects.registration_changed);
  ASSERT_EQ(step.effects.start_jobs, std::vector<JobKind>{JobKind::kMarkerDetection});
  const FiducialDetectionJob job = *pendingDetection(step.session);
  EXPECT_EQ(job.job, step.session.revision);
  EXPECT_EQ(job.volume, phantomCt().volume);  // the loaded CT, shared, not copied
  EXPECT_EQ(job.model_mm.size(), 3u);
  journal.insert(journal.end(), step.effects.journal.begin(), step.effects.journal.end());
  s = step.session;

  // One detection at a time.
  const auto again = reduce(s, command(InputKind::kAutoFiducials, 3));
  EXPECT_EQ(again.effects.replies.at(0).error_code, "busy");
  EXPECT_EQ(again.session.revision, s.revision);

  // The server's detector thread, played here.
  const Input found = detectFiducials(job);
  ASSERT_EQ(found.kind, InputKind::kFiducialsDetected) << found.error;
  EXPECT_EQ(found.job, job.job);
  EXPECT_EQ(found.points.size(), 3u);
  step = reduce(s, found);
  EXPECT_EQ(step.session.phase, Phase::kPlanning);
  EXPECT_EQ(step.session.detecting, 0u);
  // What a client waiting on the job it started (the reply's job) is told.
  ASSERT_TRUE(step.effects.job_outcome.has_value());
  EXPECT_EQ(step.effects.job_outcome->job, job.job);
  EXPECT_EQ(step.effects.job_outcome->status, "done");
  EXPECT_EQ(step.effects.job_outcome->message, found.summary);
  EXPECT_EQ(step.effects.job_outcome->revision, step.session.revision);
  EXPECT_TRUE(step.effects.replies.empty());  // the server's own input: nobody to answer
  expectTrueRegistration(step.session);
  // Journaled with the points it registered from.
  ASSERT_EQ(step.effects.journal.size(), 1u);
  const auto record = parseJournalRecord(step.effects.journal[0]);
  ASSERT_TRUE(record.ok()) << record.error().message;
  EXPECT_EQ(record->input.kind, InputKind::kFiducialsDetected);
  EXPECT_EQ(record->input.points, found.points);  // bit-exact through the text
  EXPECT_EQ(record->input.job, job.job);
  journal.insert(journal.end(), step.effects.journal.begin(), step.effects.journal.end());
  const Session live = step.session;

  // Replay registers from the journal, without detecting again: with a CT that holds no markers
  // at all, the same registration, bit for bit.
  const CtLoader no_markers = [](const std::string&) -> Expected<LoadedCt> { return emptyCt(); };
  auto replayed =
      replayJournal(newSession("t", paperRobot(), "robot.yaml"), journal, no_markers, "journal");
  ASSERT_TRUE(replayed.ok()) << replayed.error().message;
  EXPECT_EQ(replayed->phase, Phase::kPlanning);
  ASSERT_TRUE(replayed->registration.has_value());
  EXPECT_EQ(replayed->registration->imageToRobot(), live.registration->imageToRobot());
  EXPECT_EQ(replayed->registration_status.message, live.registration_status.message);
}

TEST(Detection, AnOutcomeForACtNoLongerLoadedOrARegistrationGivenMeanwhileIsIgnored) {
  Session s = registrationSession(phantomCt());
  auto started = reduce(s, command(InputKind::kAutoFiducials, 2));
  const Input found = runStartedJob(started);
  ASSERT_EQ(found.kind, InputKind::kFiducialsDetected);

  // Another CT asked for while the detection ran: whenever the outcome comes, it is refused with
  // a note and changes nothing.
  auto reloading = reduce(started.session, command(InputKind::kLoadVolume, 3));
  ASSERT_TRUE(reloading.effects.replies.at(0).accepted);
  for (const Session& now :
       {reloading.session,
        reduce(reloading.session, loaded(reloading.session, emptyCt())).session}) {
    const auto step = reduce(now, found);
    EXPECT_EQ(step.effects.replies.at(0).error_code, "stale_detection");
    const std::string& note = step.effects.replies.at(0).message;
    EXPECT_NE(note.find(fmt::format("marker detection #{} on phantom: ignored",
                                    started.session.detecting)),
              std::string::npos)
        << note;
    EXPECT_NE(note.find("the CT it ran on is no longer loaded"), std::string::npos) << note;
    ASSERT_TRUE(step.effects.job_outcome.has_value());
    EXPECT_EQ(step.effects.job_outcome->status, "stale");
    EXPECT_EQ(step.effects.job_outcome->message, note);
    EXPECT_FALSE(step.session.registration.has_value());
    EXPECT_EQ(step.session.revision, now.revision);
    EXPECT_EQ(step.session.phase, now.phase);
    EXPECT_TRUE(step.effects.journal.empty());
  }

  // Three points clicked while it ran: they win; the outcome is ignored when it comes.
  auto clicked =
      reduce(started.session, command(InputKind::kSetFiducials, 4, truth().spec.fiducials_lps_mm));
  ASSERT_TRUE(clicked.effects.replies.at(0).accepted);
  EXPECT_NE(clicked.effects.replies.at(0).message.find("dropped"), std::string::npos);
  EXPECT_EQ(clicked.session.detecting, 0u);
  const auto late = reduce(clicked.session, found);
  EXPECT_EQ(late.effects.replies.at(0).error_code, "stale_detection");
  EXPECT_FALSE(late.session.registration_status.auto_detected);
  EXPECT_EQ(late.session.registration->image_mm, clicked.session.registration->image_mm);
}

TEST(Detection, AnOutcomeThatComesWhileStoppedIsKeptAndResumeGoesOnToPlanning) {
  Session s = registrationSession(phantomCt());
  auto step = reduce(s, command(InputKind::kAutoFiducials, 2));
  const Input found = runStartedJob(step);
  step = reduce(step.session, command(InputKind::kStop, 3));
  ASSERT_EQ(step.session.phase, Phase::kStopped);
  step = reduce(step.session, found);
  EXPECT_EQ(step.session.phase, Phase::kStopped);
  expectTrueRegistration(step.session);
  step = reduce(step.session, command(InputKind::kResume, 4));
  EXPECT_EQ(step.session.phase, Phase::kPlanning);
}

TEST(Detection, AFailedDetectionSaysWhyAndAnEarlierRegistrationStays) {
  // No markers on the CT, no registration before: rejected, with the reason.
  Session s = registrationSession(emptyCt());
  auto step = reduce(s, command(InputKind::kAutoFiducials, 2));
  const Input failed = runStartedJob(step);
  ASSERT_EQ(failed.kind, InputKind::kFiducialDetectionFailed);
  EXPECT_FALSE(failed.error.empty());
  step = reduce(step.session, failed);
  EXPECT_EQ(step.session.phase, Phase::kRegistration);
  EXPECT_EQ(step.session.registration_status.status, "rejected");
  ASSERT_TRUE(step.effects.job_outcome.has_value());
  EXPECT_EQ(step.effects.job_outcome->status, "failed");
  EXPECT_EQ(step.effects.job_outcome->message, failed.error);
  EXPECT_EQ(step.session.registration_status.message, "marker detection failed: " + failed.error);
  ASSERT_EQ(step.effects.journal.size(), 1u);
  EXPECT_EQ(parseJournalRecord(step.effects.journal[0])->input.error, failed.error);

  // Registered by hand, then a detection that fails: the registration stays in use, and the lock
  // waits for the detection's outcome.
  step = reduce(step.session, command(InputKind::kSetFiducials, 3, truth().spec.fiducials_lps_mm));
  ASSERT_EQ(step.session.phase, Phase::kPlanning);
  const auto before = *step.session.registration;
  step = reduce(step.session, command(InputKind::kAddTarget, 4,
                                      {before.toImage(Eigen::Vector3d(8.0, 12.0, -175.0))}));
  ASSERT_TRUE(step.effects.replies.at(0).accepted);
  step = reduce(step.session, command(InputKind::kAutoFiducials, 5));
  EXPECT_EQ(step.session.registration_status.status, "detecting");
  EXPECT_TRUE(step.session.registration.has_value());
  const Input failed_again = runStartedJob(step);
  const auto lock = reduce(step.session, command(InputKind::kLockPlan, 6));
  EXPECT_EQ(lock.effects.replies.at(0).error_code, "busy");
  step = reduce(step.session, failed_again);
  EXPECT_EQ(step.session.phase, Phase::kPlanning);
  EXPECT_EQ(step.session.registration_status.status, "registered");
  EXPECT_EQ(step.session.registration_status.message.rfind("marker detection failed: ", 0), 0u);
  EXPECT_EQ(step.session.registration->imageToRobot(), before.imageToRobot());
  EXPECT_TRUE(
      reduce(step.session, command(InputKind::kLockPlan, 7)).effects.replies.at(0).accepted);
}

// A journal recorded before issue 22 (format 1: the demo's scripted client, configs/demo/plan.yaml,
// against the server built from main before the detection moved; session folder
// "format1_session"): its auto_fiducials detected and registered within one step. It still
// replays, record for record, to the revisions and phases it recorded, and the approvals'
// digests, which hash the session id and the steps the registration gave, match.
TEST(Detection, AJournalOfFormat1WhoseAutoFiducialsRegisteredAtOnceStillReplays) {
  std::ifstream in(IGNAV_SOURCE_DIR "/tests/workflow/data/journal_format1.jsonl");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);)
    lines.push_back(line);
  ASSERT_EQ(lines.size(), 26u);
  ASSERT_NE(lines[3].find("\"input\":\"auto_fiducials\",\"phase\":\"planning\""),
            std::string::npos);
  const CtLoader phantom = [](const std::string& source) -> Expected<LoadedCt> {
    EXPECT_EQ(source, "phantom:");
    return phantomCt();
  };
  const auto start = newSession("format1_session", paperRobot(), "robot.yaml");
  Session s = start;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    auto replayed = replayRecord(s, lines[i], phantom, "line " + std::to_string(i + 1));
    ASSERT_TRUE(replayed.ok()) << replayed.error().message;
    s = std::move(replayed->step.session);
    if (i == 3) {
      EXPECT_EQ(s.phase, Phase::kPlanning);
      EXPECT_EQ(s.detecting, 0u);  // registered at once: nothing awaited
      expectTrueRegistration(s);
    }
  }
  EXPECT_EQ(s.revision, 26u);
  EXPECT_EQ(s.phase, Phase::kDone);
  EXPECT_EQ(s.targets.size(), 3u);
  EXPECT_EQ(s.motions.size(), 4u);  // three targets and the retraction, each approved
  // New records are format 2, and a journal may go on with them after format-1 ones.
  auto step = reduce(s, command(InputKind::kUnlockPlan, 98));
  ASSERT_TRUE(step.effects.replies.at(0).accepted) << step.effects.replies.at(0).message;
  std::vector<std::string> continued = lines;
  continued.push_back(step.effects.journal.at(0));
  step = reduce(step.session, command(InputKind::kAutoFiducials, 99));
  ASSERT_TRUE(step.effects.replies.at(0).accepted);
  EXPECT_NE(step.effects.journal.at(0).find("\"v\":2"), std::string::npos);
  continued.push_back(step.effects.journal.at(0));
  auto replayed = replayJournal(start, continued, phantom, "journal");
  ASSERT_TRUE(replayed.ok()) << replayed.error().message;
  EXPECT_EQ(replayed->registration_status.status, "detecting");
  // What a restarted server runs again.
  const auto pending = pendingJobs(*replayed);
  ASSERT_EQ(pending.size(), 1u);
  EXPECT_EQ(pending[0].kind, JobKind::kMarkerDetection);
  EXPECT_EQ(pending[0].id, 28u);
  EXPECT_FALSE(
      parseJournalRecord(R"({"v":3,"input":"query","t":0,"revision":1,"phase":"x"})").ok());
}

}  // namespace
}  // namespace ignav::workflow
