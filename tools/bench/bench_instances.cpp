// What Cyclone DDS keeps in a writer's process for each target instance ever written and then
// removed (docs/RELIABILITY.md L3): N targets written and removed one after another on the
// server's target topic (transient-local, keep-last 1), with a viewer in another process, and
// glibc's bytes in use (mallinfo2) compared before and after. Removal as the server does it
// (dispose, then unregister: Writer::dispose) or as it did before (dispose only).
//   build/tools/bench/bench_instances [--targets 20000] [--ids 0] [--domain 96]
// runs both, each in a fresh process with a viewer process of its own. With --ids N the targets
// cycle through N ids, as a topic keyed by a slot would: whether what is kept is per target
// removed or per id ever used.
#include <malloc.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <string>
#include <thread>

#include "ignav/protocol/topics.hpp"
#include "ignav/protocol/wire/dds.hpp"
#include "ignav/protocol/wire/messages.hpp"

namespace {

using namespace ignav::protocol;
using namespace std::chrono_literals;

struct Options {
  int targets = 20000;
  int ids = 0;  // distinct ids cycled through; 0: every target a new id
  std::uint32_t domain = 96;
};

std::string loopback() {
  return readConfigFile(IGNAV_SOURCE_DIR "/configs/dds/loopback.xml");
}

[[noreturn]] void viewer(std::uint32_t domain, int seconds) {
  Participant p(domain, loopback(), nullptr, "robot-1");
  Reader<ignav_msg_TargetState> r(p, &ignav_msg_TargetState_desc, topic::kTarget, Qos::kState);
  for (int i = 0; i < seconds * 20; ++i) {
    r.takeWithState([](const ignav_msg_TargetState&, bool) {});
    std::this_thread::sleep_for(50ms);
  }
  _exit(0);
}

// Bytes in use per target, in this process.
double perTarget(const Options& o, bool unregister) {
  Participant server(o.domain, loopback(), nullptr, "robot-1");
  Writer<ignav_msg_TargetState> w(server, &ignav_msg_TargetState_desc, topic::kTarget, Qos::kState);
  for (int i = 0; i < 1000 && w.matched() < 1; ++i)
    std::this_thread::sleep_for(10ms);
  if (w.matched() < 1) throw std::runtime_error("the viewer never matched");
  const std::string text = "reachable";
  // A target written, then removed the way this run measures.
  auto writeAndRemove = [&](std::uint32_t id) {
    ignav_msg_TargetState t{};
    t.id = id;
    t.reach = t.message = cstr(text);
    w.write(t);
    if (unregister) {
      w.dispose(t);
    } else {
      check(dds_dispose(w.handle(), &t), "dds_dispose");
    }
  };
  // One target first, so that tables made on first use are in the baseline.
  writeAndRemove(1);
  std::this_thread::sleep_for(500ms);
  const double before = static_cast<double>(mallinfo2().uordblks);
  for (int i = 2; i <= o.targets + 1; ++i) {
    writeAndRemove(static_cast<std::uint32_t>(o.ids > 0 ? 2 + (i - 2) % o.ids : i));
    if (i % 100 == 0) std::this_thread::sleep_for(1ms);  // a viewer's pace, acks flowing
  }
  std::this_thread::sleep_for(2s);  // acknowledged and collected
  return (static_cast<double>(mallinfo2().uordblks) - before) / o.targets;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app("bytes a DDS writer keeps per removed target instance");
  app.add_option("--targets", o.targets, "targets written and removed")
      ->check(CLI::Range(1, 1000000));
  app.add_option("--ids", o.ids, "distinct ids the targets cycle through (0: a new id each)")
      ->check(CLI::Range(0, 1000000));
  app.add_option("--domain", o.domain, "DDS domain")->check(CLI::Range(0, 232));
  CLI11_PARSE(app, argc, argv);
  std::printf(
      "%d targets written and removed (%s), a viewer in another process:\n", o.targets,
      o.ids > 0 ? (std::to_string(o.ids) + " ids cycled through").c_str() : "each a new id");
  for (const bool unregister : {false, true}) {
    // Each way in fresh processes: Cyclone's tables and glibc's heap start alike.
    int pipe_fd[2];
    if (pipe(pipe_fd) != 0) return 1;
    const pid_t v = fork();
    if (v == 0) viewer(o.domain, 120);
    const pid_t w = fork();
    if (w == 0) {
      const double bytes = perTarget(o, unregister);
      if (write(pipe_fd[1], &bytes, sizeof bytes) != sizeof bytes) _exit(1);
      _exit(0);
    }
    double bytes = 0;
    const bool got = read(pipe_fd[0], &bytes, sizeof bytes) == sizeof bytes;
    waitpid(w, nullptr, 0);
    kill(v, SIGTERM);
    waitpid(v, nullptr, 0);
    close(pipe_fd[0]);
    close(pipe_fd[1]);
    if (!got) return 1;
    std::printf("  %-26s %7.0f bytes in use per target, kept\n",
                unregister ? "disposed and unregistered" : "disposed only", bytes);
  }
  return 0;
}
