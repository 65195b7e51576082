// runServer: from the options to a running Server. Loads the robot and the tissue profile, then
// either replays a recorded session (read only) or opens the session folder, recovers its journal
// (a record torn by a crash is cut off) and serves.
#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/oflog/oflog.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <ctime>
#include <filesystem>
#include <fstream>
#include <optional>

#include "ignav/igtl/brp.hpp"
#include "server.hpp"
#include "server_core.hpp"
#include "session_lock.hpp"

namespace ignav::server {
namespace {

namespace fs = std::filesystem;

std::string sessionName() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y%m%dT%H%M%SZ", &tm);
  return std::string(buf) + "-" + std::to_string(::getpid());
}

// The session a marker names, if the marker and the folder exist.
std::optional<fs::path> unfinishedSession(const fs::path& marker) {
  std::ifstream in(marker);
  std::string name;
  if (!std::getline(in, name) || name.empty()) return std::nullopt;
  const fs::path dir = marker.parent_path() / name;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return std::nullopt;
  return dir;
}

bool markUnfinished(const fs::path& marker, const fs::path& dir) {
  std::ofstream out(marker, std::ios::trunc);
  out << dir.filename().string() << "\n";
  out.flush();
  if (!out) {
    spdlog::error("{}: cannot write the unfinished-session marker", marker.string());
    return false;
  }
  return true;
}

}  // namespace

int runServer(const ServerOptions& given, const std::atomic<bool>& stop) {
  // DCMTK's IOD modules (RT Structure Sets, SEG) warn of every optional attribute a file lacks:
  // noise in the server's log. Their errors still show; the readers' own errors name the file.
  for (const char* module : {"dcmtk.dcmrt", "dcmtk.dcmiod", "dcmtk.dcmseg", "dcmtk.dcmfg"})
    OFLog::getLogger(module).setLogLevel(OFLogger::ERROR_LOG_LEVEL);
  ServerOptions options = given;
  // The network settings first: a wrong interface is named here, not as Cyclone's "Error".
  try {
    options.dds_config_xml = options.dds_config.empty()
                                 ? ""
                                 : protocol::loadDdsConfig(options.dds_config, options.dds_site);
  } catch (const protocol::DdsError& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
  // The identity as Cyclone's plugins will judge it: a wrong one is a configuration error, named
  // here (exit 2, which systemd does not restart), not a participant that fails after the session
  // folder was made.
  if (!options.security.identity.empty()) {
    try {
      const auto id = securityIdentity(options.security);
      if (const std::string bad = protocol::identityProblem(id); !bad.empty()) {
        spdlog::error("security.identity {}: {}", options.security.identity, bad);
        return 2;
      }
    } catch (const protocol::DdsError& e) {
      spdlog::error("security.identity: {}", e.what());
      return 2;
    }
  }
  // A site that lets OpenIGTLink release motion makes the bridge an approver (by its reserved id).
  if (options.openigtlink.enabled && options.openigtlink.allow_motion_approval) {
    options.approvers.push_back(igtl::kBridgeClientId);
  }
  auto robot = config::loadRobot(options.robot_config);
  if (!robot) {
    spdlog::error("{}", robot.error().message);
    return 2;
  }
  if (!options.tissue_name.empty()) {
    auto profiles = config::loadTissueProfiles(options.tissue_profiles);
    auto profile = profiles ? config::tissueProfile(*profiles, options.tissue_name)
                            : Expected<config::TissueProfile>(profiles.error());
    if (!profile) {
      spdlog::error("{}", profile.error().message);
      return 2;
    }
    options.tissue = std::move(profile).value();
  }
  if (!options.site_path.empty()) {
    auto site = anatomy::readSite(options.site_path);
    if (!site) {
      spdlog::error("{}", site.error().message);
      return 2;
    }
    options.site = std::move(site).value();
  }
  if (!options.replay_session.empty()) {
    // Read only: a torn last record is left out, not cut off the file.
    const fs::path dir(options.replay_session);
    const std::string journal_path = (dir / "journal.jsonl").string();
    if (!fs::exists(journal_path)) {
      spdlog::error("{}: no journal in this folder", journal_path);
      return 2;
    }
    auto contents = journal::readJournal(journal_path);
    if (!contents) {
      spdlog::error("{}", contents.error().message);
      return 2;
    }
    if (contents->torn_tail)
      spdlog::warn("{}: the last record was cut short; left out", journal_path);
    try {
      Server server(options, std::make_shared<const config::Robot>(std::move(robot).value()), dir,
                    std::nullopt);
      return server.replay(stop, contents->lines);
    } catch (const protocol::DdsError& e) {
      spdlog::error("DDS: {}", e.what());
      return 1;
    }
  }
  // A server started without a session folder makes a new one in session_root, unless its last
  // one there did not end cleanly (a crash, a watchdog kill): then it continues that one, as a
  // service that systemd restarts must (crash recovery). The marker names it until a clean stop.
  const fs::path root = options.session_root.empty() ? "sessions" : options.session_root;
  const fs::path marker = root / (".unfinished-" + options.robot_id);
  fs::path dir = options.session_dir;
  bool continuing = false;
  if (dir.empty()) {
    if (auto unfinished = unfinishedSession(marker)) {
      dir = *unfinished;
      continuing = true;
    } else {
      dir = root / sessionName();
    }
  }
  std::error_code ec;
  const bool made_here = !fs::exists(dir, ec);
  fs::create_directories(dir, ec);
  if (ec) {
    spdlog::error("{}: cannot create the session folder: {}", dir.string(), ec.message());
    return 2;
  }
  // One process per session folder, for its whole life, before the journal is read (a second
  // server would cut a "torn" record the first is writing, and append beside it). The marker is
  // left to its owner: a refused server touches nothing.
  std::optional<SessionLock> lock;
  if (auto locked = SessionLock::acquire(dir); locked) {
    lock.emplace(std::move(locked).value());
  } else {
    spdlog::error("{}", locked.error().message);
    return locked.error().reason == "in_use" ? 4 : 2;
  }
  if (continuing) {
    spdlog::warn("{}: the last session did not end cleanly: continuing it", dir.string());
  }
  // An existing session is recovered from its journal; a write torn by a crash is cut off.
  const std::string journal_path = (dir / "journal.jsonl").string();
  auto contents = journal::readJournal(journal_path);
  if (!contents) {
    spdlog::error("{}", contents.error().message);
    return 2;
  }
  if (contents->torn_tail) {
    spdlog::warn("{}: the last record was cut short (a crash while writing); dropped",
                 journal_path);
    fs::resize_file(journal_path, contents->valid_bytes, ec);
    if (ec) {
      spdlog::error("{}: cannot drop the torn record: {}", journal_path, ec.message());
      return 2;
    }
  }
  auto journal = journal::Journal::open(journal_path);
  if (!journal) {
    spdlog::error("{}", journal.error().message);
    return 2;
  }
  if (options.session_dir.empty() && !markUnfinished(marker, dir)) return 2;
  int code = 1;
  bool touched_controller = false;
  try {
    Server server(options, std::make_shared<const config::Robot>(std::move(robot).value()), dir,
                  std::move(journal).value());
    code = server.run(stop, contents->lines);
    touched_controller = server.touchedController();
  } catch (const protocol::DdsError& e) {
    spdlog::error("DDS: {}", e.what());
  }
  // Ended cleanly, or gave way to another server that has this robot before touching the
  // controller: nothing to continue. A new session that gave way before it touched the controller
  // is removed with its folder if this process made it (it holds the configuration alone); one
  // that halted the robot on its way out keeps the record of that halt.
  const bool gave_way = code == 4 && contents->lines.empty();
  if (options.session_dir.empty() && (code == 0 || gave_way)) fs::remove(marker, ec);
  if (gave_way && made_here && !touched_controller) {
    lock.reset();  // the lock goes before its folder
    fs::remove_all(dir, ec);
  }
  return code;
}

}  // namespace ignav::server
