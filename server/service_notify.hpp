// systemd's service protocol (sd_notify, the Debian package's Type=notify unit): READY=1 once the
// server serves, WATCHDOG=1 from the event loop while it turns, STOPPING=1 on the way out. Outside
// systemd (no NOTIFY_SOCKET) every call does nothing.
#pragma once

#include <chrono>
#include <string>

namespace ignav::server {

class ServiceNotifier {
 public:
  ServiceNotifier();
  // READY=1 with a STATUS line for `systemctl status` ("robot-1 on domain 0, session ...").
  void ready(const std::string& status);
  // WATCHDOG=1 at most every half watchdog period (WATCHDOG_USEC); called from the event loop,
  // so a wedged event thread is what the watchdog sees.
  void alive();
  void stopping();

 private:
  using Clock = std::chrono::steady_clock;
  std::chrono::microseconds watchdog_{0};  // 0: no watchdog asked for
  Clock::time_point last_ping_{};
};

}  // namespace ignav::server
