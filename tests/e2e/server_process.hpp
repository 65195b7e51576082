// A real ignav-server process for end-to-end tests: started on its own DDS domain (loopback
// config), ready when it prints its readiness line, stopped with SIGTERM, killed with the test
// process if that dies first.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "ignav/protocol/client.hpp"
#include "ignav/protocol/config.hpp"

extern char** environ;

namespace ignav::e2e {

inline std::string loopbackXml() {
  return protocol::readConfigFile(IGNAV_SOURCE_DIR "/configs/dds/loopback.xml");
}

// A state topic's field as a client last saw it: "" (stateText) or none (stateCount) while that
// topic has not arrived. Each state topic arrives on its own, and operator[] of a const json on a
// missing key is undefined: an assertion in the sanitizer build, which aborts the test binary.
inline const nlohmann::json* stateField(const nlohmann::json& s, const char* topic,
                                        const char* key) {
  if (!s.contains(topic) || !s[topic].is_object() || !s[topic].contains(key)) return nullptr;
  return &s[topic][key];
}
inline std::string stateText(const nlohmann::json& s, const char* topic, const char* key) {
  const auto* f = stateField(s, topic, key);
  return f && f->is_string() ? f->get<std::string>() : "";
}
inline std::optional<std::uint64_t> stateCount(const nlohmann::json& s, const char* topic,
                                               const char* key) {
  const auto* f = stateField(s, topic, key);
  if (!f || !f->is_number_unsigned()) return std::nullopt;
  return f->get<std::uint64_t>();
}
inline bool phaseIs(const nlohmann::json& s, const char* phase) {
  return stateText(s, "workflow", "phase") == phase;
}

// The registration a client sees, as a 4x4 image -> robot matrix.
// A point of a JSON view ([x, y, z]).
inline Eigen::Vector3d vec(const nlohmann::json& p) {
  return {p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>()};
}

inline Eigen::Matrix4d imageToRobot(const nlohmann::json& state) {
  return protocol::matrixFromState(state.at("registration").at("image_to_robot"));
}

// A target's state as a client sees it (its JSON view), by id.
inline const nlohmann::json& targetState(const nlohmann::json& state, std::uint32_t id) {
  return state["targets"][std::to_string(id)];
}

// Where a robot-frame point lies in the image: the click a user would make for it.
inline Eigen::Vector3d lpsOf(const nlohmann::json& state, const Eigen::Vector3d& robot_mm) {
  return (imageToRobot(state).inverse() * robot_mm.homogeneous()).head<3>();
}

// Under AddressSanitizer (tools/sanitize.sh), with other sanitized suites on both cores, the
// server's own work is several times slower: tests that bound a latency for correctness (not as
// a benchmark) widen the bound by this.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

#ifdef IGNAV_PLAN_EXE
// `ignav-plan ARGS` (2>&1 when `with_stderr`): its exit status and what it printed.
inline std::pair<int, std::string> runPlan(const std::string& args, bool with_stderr = false) {
  const std::string cmd = std::string(IGNAV_PLAN_EXE) + " " + args + (with_stderr ? " 2>&1" : "");
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return {-1, "cannot run " + cmd};
  std::string out;
  char buf[4096];
  while (std::size_t n = fread(buf, 1, sizeof buf, p))
    out.append(buf, n);
  return {pclose(p), out};
}

// `ignav-plan replay --verify` over a stopped server's session folder, which re-derives the session
// from its journal offline: its exit status and what it printed (JSON).
inline std::pair<int, std::string> replayVerified(const std::filesystem::path& session_dir) {
  return runPlan("replay " + session_dir.string() +
                 " --verify --robot " IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml");
}
#endif

inline double msOf(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double, std::milli>(d).count();
}

// A loop on a thread of its own for as long as this is in scope: `body` loops while the flag it
// is given holds; leaving the scope clears it and joins.
class LoopInBackground {
 public:
  explicit LoopInBackground(std::function<void(const std::atomic<bool>& running)> body)
      : thread_([this, body = std::move(body)] { body(running_); }) {}
  ~LoopInBackground() {
    running_ = false;
    thread_.join();
  }
  LoopInBackground(const LoopInBackground&) = delete;
  LoopInBackground& operator=(const LoopInBackground&) = delete;

 private:
  std::atomic<bool> running_{true};  // before thread_: set before the thread starts
  std::thread thread_;
};

// Another client asking `query` every `period` on its own thread, timing each answer.
class QueryWatcher {
 public:
  struct Sample {
    std::chrono::steady_clock::time_point sent;
    double ms = 0.0;  // until the reply came
    bool answered = false;
  };

  // A first query, untimed, before the watch starts: a new client's first exchange waits for DDS
  // discovery to finish on both sides (~200 ms seen with both cores busy), not for the server.
  QueryWatcher(std::unique_ptr<protocol::Client> client, std::chrono::milliseconds period)
      : client_(std::move(client)) {
    client_->send("query", {}, std::chrono::seconds(20));
    thread_ = std::thread([this, period] {
      while (!stop_) {
        const auto t = std::chrono::steady_clock::now();
        bool ok = false;
        try {
          ok = client_->send("query", {}, std::chrono::seconds(20)).accepted;
        } catch (const protocol::Timeout&) {
        }
        const double took = msOf(std::chrono::steady_clock::now() - t);
        if (ok) ++answered_;
        if (took > worst_ms_) worst_ms_ = took;
        {
          std::lock_guard<std::mutex> lock(mutex_);
          samples_.push_back({t, took, ok});
        }
        std::this_thread::sleep_for(period);
      }
    });
  }
  ~QueryWatcher() { stop(); }
  QueryWatcher(const QueryWatcher&) = delete;
  QueryWatcher& operator=(const QueryWatcher&) = delete;
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  int answered() const { return answered_; }
  double worstMs() const { return worst_ms_; }
  // Every query so far, in the order sent.
  std::vector<Sample> samples() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return samples_;
  }

 private:
  std::unique_ptr<protocol::Client> client_;
  mutable std::mutex mutex_;
  std::vector<Sample> samples_;
  std::atomic<bool> stop_{false};
  std::atomic<int> answered_{0};
  std::atomic<double> worst_ms_{0.0};
  std::thread thread_;
};

// Loads the phantom and registers on its markers.
inline void registeredPhantom(protocol::Client& c) {
  using namespace std::chrono_literals;
  EXPECT_TRUE(c.send("load_volume", {"phantom:", {}, {}}).accepted);
  c.waitFor([](const nlohmann::json& s) { return stateText(s, "volume", "status") == "loaded"; },
            60s);
  EXPECT_TRUE(c.send("auto_fiducials").accepted);
  c.waitFor(
      [](const nlohmann::json& s) {
        return stateText(s, "registration", "status") == "registered";
      },
      10s);
}

// registeredPhantom, then a target given in the robot frame; its id.
inline std::uint32_t plannedTarget(protocol::Client& c, const Eigen::Vector3d& robot_mm) {
  using namespace std::chrono_literals;
  registeredPhantom(c);
  const auto added = c.send("add_target", {"", {lpsOf(c.state(), robot_mm)}, {}});
  EXPECT_TRUE(added.accepted) << added.message;
  // Its state travels apart from the reply: callers read it next (under load it came later).
  const std::string id = std::to_string(added.target_id);
  c.waitFor(
      [&](const nlohmann::json& s) { return s.contains("targets") && s["targets"].contains(id); },
      10s);
  return added.target_id;
}

inline void lockAndWaitForApproval(protocol::Client& c) {
  using namespace std::chrono_literals;
  const auto locked = c.send("lock_plan");
  EXPECT_TRUE(locked.accepted) << locked.message;
  c.waitFor([](const nlohmann::json& s) { return stateText(s, "approval", "status") == "pending"; },
            10s);
}

// plannedTarget, then lock: an approval request for the motion to it is pending.
inline std::uint32_t lockedPlanTo(protocol::Client& c, const Eigen::Vector3d& robot_mm) {
  const auto id = plannedTarget(c, robot_mm);
  lockAndWaitForApproval(c);
  return id;
}

// Approves the request the approval state shows, exactly as shown.
inline protocol::Reply approveShown(protocol::Client& c) {
  c.poll();
  const nlohmann::json& a = c.state()["approval"];
  return c.approve(a["plan_id"].get<std::uint64_t>(), a["digest"].get<std::string>());
}

// Plans the targets (robot frame) and moves to each in turn, approving every motion as shown,
// until the procedure is done. Returns the targets' ids.
inline std::vector<std::uint32_t> insertAll(protocol::Client& op,
                                            const std::vector<Eigen::Vector3d>& targets_robot) {
  std::vector<std::uint32_t> ids{plannedTarget(op, targets_robot.front())};
  for (std::size_t i = 1; i < targets_robot.size(); ++i) {
    const auto added = op.send("add_target", {"", {lpsOf(op.state(), targets_robot[i])}, {}});
    EXPECT_TRUE(added.accepted) << added.message;
    ids.push_back(added.target_id);
  }
  lockAndWaitForApproval(op);
  for (std::size_t motion = 0; motion <= targets_robot.size(); ++motion) {
    op.waitFor(
        [](const nlohmann::json& s) { return stateText(s, "approval", "status") == "pending"; },
        std::chrono::seconds(10));
    const auto approved = approveShown(op);
    EXPECT_TRUE(approved.accepted) << approved.message;
    op.waitFor(
        [&](const nlohmann::json& s) {
          return (phaseIs(s, "at_target") || phaseIs(s, "done")) &&
                 s["workflow"]["revision"].get<std::uint64_t>() > approved.revision &&
                 stateText(s, "motion", "state") == "idle";
        },
        std::chrono::seconds(60));
  }
  EXPECT_TRUE(phaseIs(op.state(), "done")) << op.state()["workflow"].dump();
  return ids;
}

// Whether `path` exists within `timeout`: files the server's reports thread writes come a little
// after the state that made them.
inline bool fileAppears(const std::filesystem::path& path, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!std::filesystem::exists(path) && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  return std::filesystem::exists(path);
}

// A command line run to its end (stderr with stdout): its exit code and everything it printed.
struct CommandRun {
  int exit_code = -1;
  std::string output;
};
inline CommandRun runCommand(const std::string& cmd) {
  CommandRun r;
  FILE* pipe = ::popen((cmd + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  char buf[512];
  while (std::fgets(buf, sizeof buf, pipe))
    r.output += buf;
  const int status = ::pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

#ifdef IGNAVCTL_EXE
// `ignavctl ARGS` over the loopback configuration on `domain`: its exit code and what it printed.
inline CommandRun ignavctlOn(std::uint32_t domain, const std::string& args) {
  return runCommand(std::string(IGNAVCTL_EXE) +
                    " --dds-config " IGNAV_SOURCE_DIR "/configs/dds/loopback.xml --domain " +
                    std::to_string(domain) + " " + args);
}
#endif

class ServerProcess {
  // Per test process and instance: two servers may share a domain (several robots).
  static std::filesystem::path uniqueSessionDir(std::uint32_t domain) {
    static int instances = 0;
    return std::filesystem::temp_directory_path() /
           ("ignav_e2e_" + std::to_string(::getpid()) + "_" + std::to_string(domain) + "_" +
            std::to_string(++instances));
  }

 public:
  // Each test passes its own domain id so that tests running in parallel never meet.
  // `extra_args` go on the server's command line (e.g. --controller galil:127.0.0.1:PORT).
  explicit ServerProcess(std::uint32_t domain, std::vector<std::string> extra_args = {},
                         std::vector<std::string> env = {})
      : domain_(domain), extra_args_(std::move(extra_args)), env_(std::move(env)) {
    session_dir_ = uniqueSessionDir(domain);
    std::filesystem::remove_all(session_dir_);
    start();
  }

  // Another program that serves the domain (e.g. `ignavctl replay`): `argv` whole, ready when its
  // stdout shows `ready`.
  struct Program {
    std::vector<std::string> argv;
    std::string ready;
  };
  ServerProcess(std::uint32_t domain, Program program)
      : domain_(domain), program_(std::move(program)) {
    session_dir_ = uniqueSessionDir(domain);
    std::filesystem::remove_all(session_dir_);
    start();
  }

  // The environment of the next start() (e.g. IGNAV_CRASH_AT=...); {} for the inherited one.
  void setEnv(std::vector<std::string> env) { env_ = std::move(env); }
  ~ServerProcess() {
    stop();
    std::filesystem::remove_all(session_dir_);
    std::filesystem::remove(session_dir_.string() + ".log");
  }
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  void start() {
    int out[2];
    ASSERT_EQ(::pipe(out), 0);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, out[0]);
    const std::string log = (session_dir_.string() + ".log");
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(),
                                     O_WRONLY | O_CREAT | O_APPEND, 0644);
    std::vector<std::string> args{IGNAV_SERVER_EXE,
                                  "--config",
                                  IGNAV_SOURCE_DIR "/configs/server.yaml",
                                  "--domain",
                                  std::to_string(domain_),
                                  "--session-dir",
                                  session_dir_.string()};
    // OpenIGTLink on a free port (tests run side by side); igtlPort() tells which.
    if (std::find(extra_args_.begin(), extra_args_.end(), "--igtl-port") == extra_args_.end() &&
        std::find(extra_args_.begin(), extra_args_.end(), "--no-igtl") == extra_args_.end()) {
      args.insert(args.end(), {"--igtl-port", "0"});
    }
    // Loopback discovery takes milliseconds: the robot-id check need not hold each test a second.
    if (std::find(extra_args_.begin(), extra_args_.end(), "--robot-id-check-ms") ==
        extra_args_.end()) {
      args.insert(args.end(), {"--robot-id-check-ms", "150"});
    }
    args.insert(args.end(), extra_args_.begin(), extra_args_.end());
    if (!program_.argv.empty()) args = program_.argv;
    // The server dies with this test process: one that crashed must not leave servers in their
    // domains to answer the next run's clients (util-linux's setpriv sets PR_SET_PDEATHSIG).
    args.insert(args.begin(), {"/usr/bin/setpriv", "--pdeathsig", "KILL", "--"});
    std::vector<char*> argv;
    for (auto& a : args)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    std::vector<std::string> env_text;
    for (char** e = environ; *e; ++e)
      env_text.emplace_back(*e);
    env_text.insert(env_text.end(), env_.begin(), env_.end());
    std::vector<char*> envp;
    for (auto& e : env_text)
      envp.push_back(e.data());
    envp.push_back(nullptr);
    ASSERT_EQ(posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), envp.data()), 0);
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    // The readiness line, within 20 s. (The program writes nothing to stdout after it: the pipe
    // is closed then.)
    std::string line;
    pollfd p{out[0], POLLIN, 0};
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    const std::string ready = program_.ready.empty() ? "ignav-server ready" : program_.ready;
    while (line.find(ready) == std::string::npos && std::chrono::steady_clock::now() < end) {
      if (::poll(&p, 1, 100) > 0) {
        char buf[256];
        const ssize_t n = ::read(out[0], buf, sizeof buf);
        if (n <= 0) break;
        line.append(buf, static_cast<std::size_t>(n));
      }
    }
    ::close(out[0]);
    ready_line_ = line;
    ASSERT_NE(line.find(ready), std::string::npos) << line << serverLog();
  }

  // The robot id from the readiness line ("robot-1", configs/server.yaml's, unless given).
  std::string robotId() const {
    const auto at = ready_line_.find(" robot=");
    if (at == std::string::npos) return "robot-1";  // a program that does not say (a replay)
    const auto end = ready_line_.find_first_of(" \n", at + 7);
    return ready_line_.substr(at + 7, end - at - 7);
  }

  // The OpenIGTLink port from the readiness line (0: none).
  int igtlPort() const {
    const auto at = ready_line_.find("igtl_port=");
    return at == std::string::npos ? 0 : std::atoi(ready_line_.c_str() + at + 10);
  }

  // SIGTERM and the exit code (0 for a clean shutdown).
  int stop() {
    if (pid_ <= 0) return -1;
    ::kill(pid_, SIGTERM);
    int status = 0;
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  // False once the process has exited (it is reaped then).
  bool alive() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return false;
    }
    return true;
  }

  // SIGKILL: no shutdown code runs, as in a crash or power loss.
  void crash() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }

  std::string serverLog() const {
    std::ifstream in(session_dir_.string() + ".log");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }

  std::unique_ptr<protocol::Client> client(const std::string& id) const {
    auto c = std::make_unique<protocol::Client>(domain_, loopbackXml(), id, nullptr, robotId());
    EXPECT_TRUE(c->waitForServer(std::chrono::seconds(10)));
    c->waitFor([](const nlohmann::json& s) { return s.contains("workflow"); },
               std::chrono::seconds(10));
    return c;
  }

  const std::filesystem::path& sessionDir() const { return session_dir_; }
  std::uint32_t domain() const { return domain_; }
  pid_t pid() const { return pid_; }

 private:
  std::uint32_t domain_;
  std::vector<std::string> extra_args_;
  std::string ready_line_;
  std::vector<std::string> env_;
  Program program_;
  std::filesystem::path session_dir_;
  pid_t pid_ = -1;
};

}  // namespace ignav::e2e
