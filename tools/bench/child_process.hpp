// A child process for the benchmarks that start their own server (bench_slow_controller,
// bench_igtl3): its stdout read up to a line containing `ready`, killed when it goes out of scope,
// and killed with the benchmark if that dies first (setpriv --pdeathsig).
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <stdexcept>
#include <string>
#include <vector>

namespace ignav::bench {

// A child process whose stdout is read up to a line containing `ready`; killed at the end.
class Child {
 public:
  Child(std::vector<std::string> args, const std::string& ready, const std::string& log) {
    int out[2];
    if (::pipe(out) != 0) throw std::runtime_error("pipe");
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, out[0]);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    args.insert(args.begin(), {"/usr/bin/setpriv", "--pdeathsig", "KILL", "--"});
    std::vector<char*> argv;
    for (auto& a : args)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) {
      throw std::runtime_error("cannot start " + args[4]);
    }
    posix_spawn_file_actions_destroy(&actions);
    ::close(out[1]);
    pollfd p{out[0], POLLIN, 0};
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (line_.find(ready) == std::string::npos && std::chrono::steady_clock::now() < end) {
      if (::poll(&p, 1, 100) > 0) {
        char buf[256];
        const ssize_t n = ::read(out[0], buf, sizeof buf);
        if (n <= 0) break;
        line_.append(buf, static_cast<std::size_t>(n));
      }
    }
    out_ = out[0];
    if (line_.find(ready) == std::string::npos) {
      throw std::runtime_error(args[4] + " did not start: " + line_ + " (log: " + log + ")");
    }
  }
  ~Child() {
    ::kill(pid_, SIGTERM);
    ::waitpid(pid_, nullptr, 0);
    ::close(out_);
  }
  const std::string& line() const { return line_; }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  std::string line_;
};

}  // namespace ignav::bench
