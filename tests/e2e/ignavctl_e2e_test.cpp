// ignavctl's command line (issue 39): its own options stand before or after the subcommand, and
// an alias (`targets add X,Y,Z`) reads its words by the row of the command it sends, as that
// command's own subcommand (`add-target X,Y,Z`) does. Real ignav-server and ignavctl processes
// over Cyclone DDS on loopback. Domains 225 and 226 (no server).
#include <gtest/gtest.h>

#include <string>
#include <utility>

#include "server_process.hpp"

namespace ignav::e2e {
namespace {

using nlohmann::json;

CommandRun ctl(const std::string& args) {
  return runCommand(std::string(IGNAVCTL_EXE) +
                    " --dds-config " IGNAV_SOURCE_DIR "/configs/dds/loopback.xml " + args);
}

// What it printed from its first '{' on (the warning that security is off comes first).
json jsonOf(const CommandRun& run) {
  const auto brace = run.output.find('{');
  if (brace == std::string::npos) return json();
  return json::parse(run.output.substr(brace), nullptr, false);
}

TEST(IgnavctlE2E, ItsOwnOptionsStandBeforeOrAfterTheSubcommand) {
  ServerProcess server(225);
  const auto before = ctl("--domain 225 --wait-server 10 --json status");
  const auto after = ctl("status --json --domain 225 --wait-server 10");
  ASSERT_EQ(before.exit_code, 0) << before.output;
  ASSERT_EQ(after.exit_code, 0) << after.output;
  const json b = jsonOf(before);
  const json a = jsonOf(after);
  ASSERT_TRUE(a.is_object() && b.is_object()) << after.output;
  EXPECT_EQ(stateText(a, "health", "robot_id"), server.robotId()) << after.output;
  EXPECT_EQ(stateText(a, "workflow", "phase"), "imaging") << after.output;
  EXPECT_EQ(stateText(a, "workflow", "phase"), stateText(b, "workflow", "phase"));
  EXPECT_EQ(stateText(a, "health", "session_dir"), stateText(b, "health", "session_dir"));

  // After a command's words, with a value: the reply names the client id given there.
  const auto ping = ctl("ping --domain 225 --client-id after-the-words --json");
  ASSERT_EQ(ping.exit_code, 0) << ping.output;
  const json reply = jsonOf(ping);
  ASSERT_TRUE(reply.is_object()) << ping.output;
  EXPECT_EQ(reply.value("client_id", ""), "after-the-words") << ping.output;
  EXPECT_TRUE(reply.value("accepted", false)) << ping.output;

  // After an alias's words, between a subcommand's own options.
  const auto targets = ctl("targets ls --json --domain 225");
  ASSERT_EQ(targets.exit_code, 0) << targets.output;
  EXPECT_EQ(jsonOf(targets), json::object()) << targets.output;
  const auto doctor = ctl("doctor --json --seconds 0.5 --domain 225");
  const json report = jsonOf(doctor);
  ASSERT_TRUE(report.is_object()) << doctor.output;
  EXPECT_EQ(report.value("domain", 0), 225) << doctor.output;
}

TEST(IgnavctlE2E, AnAliasReadsItsWordsByTheRowOfTheCommandItSends) {
  // alias words, the command's own subcommand: the same words after each, the same refusal and
  // usage, before ignavctl joins the domain (nothing is on domain 226).
  const std::pair<std::string, std::string> spellings[] = {
      {"targets add", "add-target"},      {"targets rm", "remove-target"},
      {"fiducials set", "set-fiducials"}, {"load", "load-volume"},
      {"ready", "check-ready"},           {"verify place", "place-seed"},
  };
  for (const auto& [alias, command] : spellings) {
    for (const std::string words : {"", " 1", " 1,2,3 4,5,6 7,8,9 0,0,0"}) {
      if (words.empty() && alias.find(' ') == std::string::npos) continue;  // CLI11's "required"
      SCOPED_TRACE(alias + words + " | " + command + words);
      const auto by_alias = ctl("--domain 226 --wait-server 0.1 " + alias + words);
      const auto by_name = ctl("--domain 226 --wait-server 0.1 " + command + words);
      if (words.empty()) {  // the alias's verb alone: the row's usage
        EXPECT_EQ(by_alias.exit_code, 2) << by_alias.output;
        EXPECT_NE(by_alias.output.find("usage: " + alias), std::string::npos) << by_alias.output;
        continue;
      }
      EXPECT_EQ(by_alias.exit_code, by_name.exit_code) << by_alias.output << by_name.output;
      if (by_alias.exit_code != 2) continue;  // words the row takes (a path): no server answers
      // The refusal, with the command's name where the alias's words stood.
      std::string expected = by_name.output;
      const auto at = expected.find("usage: " + command);
      if (at != std::string::npos) expected.replace(at + 7, command.size(), alias);
      EXPECT_EQ(by_alias.output, expected);
      EXPECT_EQ(by_alias.output.find("DDS Security is off"), std::string::npos)
          << "joined the domain: " << by_alias.output;
    }
  }
}

}  // namespace
}  // namespace ignav::e2e
