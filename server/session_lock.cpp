#include "session_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <string>

#include <fmt/format.h>

namespace ignav::server {
namespace {

std::string holderText() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) std::strcpy(host, "?");
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char when[32];
  std::strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return fmt::format("pid {} on host {}, started {}\n", ::getpid(), host, when);
}

std::string readAll(int fd) {
  std::string text;
  char buf[512];
  for (off_t at = 0;;) {
    const ssize_t n = ::pread(fd, buf, sizeof buf, at);
    if (n <= 0) break;
    text.append(buf, static_cast<std::size_t>(n));
    at += n;
    if (text.size() > 4096) break;
  }
  while (!text.empty() && (text.back() == '\n' || text.back() == '\0'))
    text.pop_back();
  return text;
}

}  // namespace

Expected<SessionLock> SessionLock::acquire(const std::filesystem::path& folder) {
  const std::string path = (folder / "session.lock").string();
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) {
    return makeError(ErrorCode::kIo, fmt::format("{}: cannot open the session lock: {}", path,
                                                 std::strerror(errno)));
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int why = errno;
    std::string holder = why == EWOULDBLOCK ? readAll(fd) : std::string();
    ::close(fd);
    if (why != EWOULDBLOCK) {
      return makeError(ErrorCode::kIo, fmt::format("{}: cannot lock the session folder: {}", path,
                                                   std::strerror(why)));
    }
    Error e{ErrorCode::kIo,
            fmt::format("{}: this session folder is in use by another ignav-server ({}); two "
                        "servers must never write one journal: stop that one first, or give this "
                        "one another session folder (--session-dir, server.session_root)",
                        folder.string(), holder.empty() ? "holder unknown" : holder),
            "in_use"};
    return e;
  }
  // Ours: say who holds it, for the next one that tries.
  const std::string me = holderText();
  if (::ftruncate(fd, 0) != 0 ||
      ::pwrite(fd, me.data(), me.size(), 0) != static_cast<ssize_t>(me.size())) {
    const int why = errno;
    ::close(fd);
    return makeError(ErrorCode::kIo, fmt::format("{}: cannot write the session lock: {}", path,
                                                 std::strerror(why)));
  }
  return SessionLock(fd);
}

SessionLock::SessionLock(SessionLock&& other) noexcept : fd_(other.fd_) {
  other.fd_ = -1;
}

SessionLock::~SessionLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the last descriptor releases the lock
}

}  // namespace ignav::server
