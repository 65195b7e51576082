#include "ignav/journal/journal.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <utility>

namespace ignav::journal {

Expected<Journal> Journal::open(const std::string& path) {
  std::error_code ec;
  const auto parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) {
    return makeError(ErrorCode::kIo, path + ": cannot open journal: " + std::strerror(errno));
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return makeError(ErrorCode::kIo, path + ": cannot stat journal: " + why);
  }
  return Journal(fd, path, static_cast<std::size_t>(st.st_size));
}

Journal::Journal(Journal&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)),
      path_(std::move(other.path_)),
      records_(other.records_),
      bytes_(other.bytes_) {}

Journal& Journal::operator=(Journal&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    path_ = std::move(other.path_);
    records_ = other.records_;
    bytes_ = other.bytes_;
  }
  return *this;
}

Journal::~Journal() {
  if (fd_ >= 0) ::close(fd_);
}

Status Journal::append(const std::string& line) {
  if (line.find('\n') != std::string::npos) {
    return makeError(ErrorCode::kInvalidArgument, "journal record spans lines");
  }
  const std::string record = line + "\n";
  // A failed record is cut off again (best effort: if even that fails, recovery drops a torn
  // last line anyway).
  auto failed = [&](const char* what) {
    const std::string why = std::strerror(errno);
    (void)::ftruncate(fd_, static_cast<off_t>(bytes_));
    return makeError(ErrorCode::kIo, path_ + ": journal " + what + " failed: " + why);
  };
  std::size_t written = 0;
  while (written < record.size()) {
    const ssize_t n = ::write(fd_, record.data() + written, record.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      return failed("write");
    }
    written += static_cast<std::size_t>(n);
  }
  if (::fdatasync(fd_) != 0) return failed("sync");
  bytes_ += record.size();
  ++records_;
  return Ok{};
}

Expected<JournalContents> readJournal(const std::string& path) {
  JournalContents out;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return out;
  std::ifstream in(path, std::ios::binary);
  if (!in) return makeError(ErrorCode::kIo, path + ": cannot read the journal");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = text.find('\n', start);
    if (end == std::string::npos) {
      out.torn_tail = true;
      break;
    }
    out.lines.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  out.valid_bytes = start;
  return out;
}

}  // namespace ignav::journal
