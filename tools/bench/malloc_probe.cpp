// Preloaded into a process by tools/bench/bench_memory.sh: every IGNAV_MALLOC_PROBE_S seconds
// (default 60) a thread of its own writes glibc's malloc_info(3) to IGNAV_MALLOC_PROBE_OUT,
// replacing the file (written aside, then renamed, so a reader never sees half of it); with
// IGNAV_MALLOC_PROBE_TRIM=1 it first calls malloc_trim(0) and prints its duration. Attaching
// gdb to call malloc_info could deadlock the server: every thread stops where it is, one of them
// perhaps holding an arena's lock that malloc_info then waits for.
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

namespace {

void probe(std::string out, int period_s, bool trim) {
  const std::string aside = out + ".part";
  for (;;) {
    if (trim) {
      const auto t = std::chrono::steady_clock::now();
      malloc_trim(0);
      std::fprintf(
          stderr, "malloc_trim %.3f ms\n",
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count());
    }
    if (FILE* f = std::fopen(aside.c_str(), "w")) {
      malloc_info(0, f);
      std::fclose(f);
      std::rename(aside.c_str(), out.c_str());
    }
    std::this_thread::sleep_for(std::chrono::seconds(period_s));
  }
}

struct Start {
  Start() {
    const char* out = std::getenv("IGNAV_MALLOC_PROBE_OUT");
    if (!out || !*out) return;
    const char* period = std::getenv("IGNAV_MALLOC_PROBE_S");
    const int period_s = period ? std::max(1, std::atoi(period)) : 60;
    const char* trim = std::getenv("IGNAV_MALLOC_PROBE_TRIM");
    std::thread(probe, std::string(out), period_s, trim && *trim == '1').detach();
  }
} start;

}  // namespace
