#include "service_notify.hpp"

#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <cstdint>

namespace ignav::server {

ServiceNotifier::ServiceNotifier() {
  std::uint64_t usec = 0;
  // > 0 only when systemd asked this process (WATCHDOG_USEC, and WATCHDOG_PID if set, is ours).
  if (sd_watchdog_enabled(0, &usec) > 0) watchdog_ = std::chrono::microseconds(usec);
}

void ServiceNotifier::ready(const std::string& status) {
  const std::string message = "READY=1\nSTATUS=" + status;
  if (sd_notify(0, message.c_str()) < 0) spdlog::warn("sd_notify READY failed");
  last_ping_ = Clock::now();
}

void ServiceNotifier::alive() {
  if (watchdog_.count() == 0) return;
  const auto now = Clock::now();
  if (now - last_ping_ < watchdog_ / 2) return;
  sd_notify(0, "WATCHDOG=1");
  last_ping_ = now;
}

void ServiceNotifier::stopping() {
  sd_notify(0, "STOPPING=1");
}

}  // namespace ignav::server
