// One server per session folder (issue 38): an advisory lock on <folder>/session.lock, held for
// the life of the process. The kernel releases it when the process dies, however it dies, so a
// crashed server's session is still continued by the next one; a second live server is refused
// before it reads or writes the journal, and is told who holds the folder.
#pragma once

#include <filesystem>
#include <string>

#include "ignav/core/expected.hpp"

namespace ignav::server {

class SessionLock {
 public:
  // Locks `folder` (which must exist) and records this process as its holder (pid, host, start).
  // Error reason "in_use": another process holds it (the message names it); otherwise the lock
  // file could not be made or locked.
  static Expected<SessionLock> acquire(const std::filesystem::path& folder);

  SessionLock(SessionLock&& other) noexcept;
  SessionLock& operator=(SessionLock&& other) = delete;
  SessionLock(const SessionLock&) = delete;
  ~SessionLock();  // releases the lock (the file stays: it names the last holder)

 private:
  explicit SessionLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

}  // namespace ignav::server
