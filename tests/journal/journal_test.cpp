#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "ignav/journal/journal.hpp"

namespace ignav::journal {
namespace {

std::filesystem::path scratch(const std::string& name) {
  auto dir =
      std::filesystem::temp_directory_path() / ("ignav_journal_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir / name;
}

TEST(Journal, AppendsLinesThatAnotherReaderSeesAtOnce) {
  const auto path = scratch("a/b/journal.jsonl");  // folders are created
  std::filesystem::remove(path);
  auto j = Journal::open(path.string());
  ASSERT_TRUE(j.ok()) << j.error().message;
  ASSERT_TRUE(j->append(R"({"n":1})").ok());
  ASSERT_TRUE(j->append(R"({"n":2})").ok());
  EXPECT_EQ(j->records(), 2u);
  std::ifstream in(path);
  std::string a, b;
  std::getline(in, a);
  std::getline(in, b);
  EXPECT_EQ(a, R"({"n":1})");
  EXPECT_EQ(b, R"({"n":2})");
  // Reopening appends, never truncates.
  auto again = Journal::open(path.string());
  ASSERT_TRUE(again->append(R"({"n":3})").ok());
  EXPECT_EQ(std::filesystem::file_size(path), 3 * std::string(R"({"n":1})"
                                                              "\n")
                                                      .size());
}

TEST(Journal, RefusesMultiLineRecordsAndUnwritablePaths) {
  auto j = Journal::open(scratch("b.jsonl").string());
  ASSERT_TRUE(j.ok());
  EXPECT_FALSE(j->append("one\ntwo").ok());
  const auto bad = Journal::open("/proc/ignav/journal.jsonl");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().code, ErrorCode::kIo);
  EXPECT_NE(bad.error().message.find("/proc/ignav/journal.jsonl"), std::string::npos);
}

TEST(Journal, ReadsBackAndDropsATornLastLine) {
  const auto path = scratch("torn.jsonl");
  {
    std::ofstream out(path, std::ios::trunc);
    out << "{\"a\":1}\n{\"b\":2}\n{\"c\":";  // the crash came mid-write
  }
  auto read = readJournal(path.string());
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(read->lines, (std::vector<std::string>{"{\"a\":1}", "{\"b\":2}"}));
  EXPECT_TRUE(read->torn_tail);
  EXPECT_EQ(read->valid_bytes, std::string("{\"a\":1}\n{\"b\":2}\n").size());
  const auto missing = readJournal(scratch("none.jsonl").string());
  ASSERT_TRUE(missing.ok());
  EXPECT_TRUE(missing->lines.empty());
  EXPECT_FALSE(missing->torn_tail);
}

}  // namespace
}  // namespace ignav::journal
