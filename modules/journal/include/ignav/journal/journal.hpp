// The session journal: one JSON record per line, appended and flushed to disk (fdatasync)
// before the server publishes the effects of the input it records (DESIGN.md invariant 4).
#pragma once

#include <string>
#include <vector>

#include "ignav/core/expected.hpp"

namespace ignav::journal {

class Journal {
 public:
  // Creates the file (and its folder) or appends to it.
  static Expected<Journal> open(const std::string& path);
  Journal(Journal&& other) noexcept;
  Journal& operator=(Journal&& other) noexcept;
  Journal(const Journal&) = delete;
  Journal& operator=(const Journal&) = delete;
  ~Journal();

  // One line (no newline inside); durable when this returns Ok. On an error (disk full, a file
  // size limit, I/O) the file is cut back to its last whole record, so a later append or a
  // recovery never meets half a record.
  Status append(const std::string& line);
  const std::string& path() const { return path_; }
  std::size_t records() const { return records_; }

 private:
  Journal(int fd, std::string path, std::size_t bytes)
      : fd_(fd), path_(std::move(path)), bytes_(bytes) {}
  int fd_ = -1;
  std::string path_;
  std::size_t records_ = 0;
  std::size_t bytes_ = 0;  // the file's size after the last whole record
};

// The records of a journal file. A last line without its newline is a write cut short by a crash
// or power loss: it is dropped (torn_tail) and valid_bytes says where the good part ends, so
// the file can be truncated there before appending again.
struct JournalContents {
  std::vector<std::string> lines;
  bool torn_tail = false;
  std::size_t valid_bytes = 0;
};
// A missing file reads as empty.
Expected<JournalContents> readJournal(const std::string& path);

}  // namespace ignav::journal
