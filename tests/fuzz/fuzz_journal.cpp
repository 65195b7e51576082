// The journal reader: a mutated journal (lines of JSON) is parsed record by record and replayed
// onto a fresh session, as recovery and offline replay do. Bad records are refused with a
// message; nothing crashes.
#include <memory>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "ignav/config/robot_config.hpp"
#include "ignav/journal/journal.hpp"
#include "ignav/workflow/reducer.hpp"

namespace {
std::shared_ptr<const ignav::config::Robot> robot() {
  static const auto r = std::make_shared<const ignav::config::Robot>(
      ignav::config::loadRobot(IGNAV_SOURCE_DIR "/configs/robots/torabi2014.yaml").value());
  return r;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = ignav::fuzz::scratchFile(data, size, ".jsonl");
  auto contents = ignav::journal::readJournal(path);
  if (!contents.ok()) return 0;
  for (const auto& line : contents->lines)
    (void)ignav::workflow::parseJournalRecord(line);
  // The CT named by a load record is never read here.
  const ignav::workflow::CtLoader no_ct = [](const std::string& source) {
    return ignav::Expected<ignav::workflow::LoadedCt>(
        ignav::makeError(ignav::ErrorCode::kIo, source + ": not loaded while fuzzing"));
  };
  (void)ignav::workflow::replayJournal(ignav::workflow::newSession("fuzz", robot(), "robot.yaml"),
                                       contents->lines, no_ct, "fuzz.jsonl");
  return 0;
}
