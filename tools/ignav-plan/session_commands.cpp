#include "session_commands.hpp"

#include <filesystem>
#include <memory>

#include "ignav/config/robot_config.hpp"
#include "ignav/journal/journal.hpp"
#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/reducer.hpp"

namespace ignav::plan {

ReplayedSession replayedSession(const ReplayArgs& args) {
  namespace fs = std::filesystem;
  const fs::path dir(args.session_dir);
  const std::string journal_path = (dir / "journal.jsonl").string();
  if (!fs::exists(journal_path)) throw CliError{journal_path + ": no journal in this folder"};
  auto robot = config::loadRobot(args.robot_path);
  if (!robot) throw CliError{robot.error().message};
  auto contents = journal::readJournal(journal_path);
  if (!contents) throw CliError{contents.error().message};

  const auto start = workflow::newSession(
      dir.filename().string(), std::make_shared<const config::Robot>(std::move(robot).value()),
      args.robot_path);
  // The CT load's own run, as the server's recovery reads a journaled CT again (the built-in
  // phantom from the series the server wrote into the session).
  auto load_ct = [&](const std::string& source) -> Expected<workflow::LoadedCt> {
    workflow::Input loaded = workflow::loadCt(0, source, *start.robot, {dir, {}});
    if (loaded.kind != workflow::InputKind::kVolumeLoaded) {
      return makeError(ErrorCode::kIo, loaded.error);
    }
    return loaded.loaded;
  };
  auto session = workflow::replayJournal(start, contents->lines, load_ct, journal_path);
  if (!session) throw CliError{session.error().message};
  return {std::move(session).value(), contents->lines.size(), contents->torn_tail};
}

nlohmann::json replaySession(const ReplayArgs& args) {
  using nlohmann::json;
  const ReplayedSession replayed = replayedSession(args);
  const workflow::Session* session = &replayed.session;

  json targets = json::array();
  for (std::size_t i = 0; i < session->targets.size(); ++i) {
    const auto& t = session->targets[i];
    const auto& j = t.commandedJoints();
    targets.push_back({{"id", t.id},
                       {"order", i + 1},
                       {"status", t.status()},
                       {"lps_mm", pointJson(t.lps_mm)},
                       {"robot_mm", pointJson(t.robot_mm)},
                       {"joints",
                        {{"theta_c_deg", j.theta_c_rad * 180.0 / M_PI},
                         {"z_c_mm", j.z_c_mm},
                         {"z_s_mm", j.z_s_mm}}},
                       {"steps", t.steps.motor},
                       {"tre_mm", t.tre_mm},
                       {"message", t.message}});
  }
  json out = {{"verified", true},
              {"records", replayed.records},
              {"torn_tail_dropped", replayed.torn_tail_dropped},
              {"revision", session->revision},
              {"phase", workflow::toString(session->phase)},
              {"volume", session->volume_status.source},
              {"targets", targets}};
  if (session->registration) {
    out["registration"] = {{"fre_mm", session->registration->fre_mm},
                           {"scale", session->registration->scale},
                           {"auto_detected", session->registration_status.auto_detected}};
  }
  return out;
}

}  // namespace ignav::plan
