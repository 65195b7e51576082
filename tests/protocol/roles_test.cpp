// The command-kind -> role table against the permissions the test PKI grants each role
// (configs/security/roles.txt, what make-test-pki.sh signs): every command's topic is published
// by its role and the roles above, never by the role below.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "ignav/commands/command_table.hpp"
#include "ignav/protocol/commands.hpp"
#include "ignav/protocol/config.hpp"
#include "ignav/protocol/security.hpp"

namespace ignav::protocol {
namespace {

// role -> the topics it may publish, as roles.txt says.
std::map<std::string, std::set<std::string>> publishedByRole() {
  std::ifstream in(IGNAV_SOURCE_DIR "/configs/security/roles.txt");
  std::map<std::string, std::set<std::string>> out;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream words(line.substr(0, line.find('|')));
    std::string role, topic;
    words >> role;
    while (words >> topic)
      out[role].insert(topic);
  }
  return out;
}

// Every command on the Command topics, from the one table that declares them.
std::vector<std::int32_t> allKinds() {
  std::vector<std::int32_t> kinds;
  for (const auto& spec : ignav::commands::inputTable())
    if (spec.wire_kind != ignav::commands::kNoWireKind) kinds.push_back(spec.wire_kind);
  return kinds;
}

std::int32_t kindOf(const char* name) {
  return commandKindFromName(name).value();
}

TEST(Roles, EveryCommandsTopicIsGrantedToItsRoleAndAboveAndNotBelow) {
  const auto granted = publishedByRole();
  ASSERT_EQ(granted.size(), 4u);  // viewer, planner, approver, service
  const auto kinds = allKinds();
  ASSERT_GE(kinds.size(), 21u);
  for (const auto kind : kinds) {
    const Role role = requiredRole(kind);
    const std::string topic = commandTopic(role);
    for (const Role r : kRoles) {
      const bool may = granted.at(toString(r)).count(topic) > 0;
      EXPECT_EQ(may, r >= role) << commandKindName(kind) << " on " << topic << " by "
                                << toString(r);
    }
    EXPECT_EQ(granted.at("service").count(topic), 0u) << topic;
  }
}

TEST(Roles, OnlyApproversApproveEveryoneStopsAndEachRoleGetsMoreThanTheLast) {
  const auto granted = publishedByRole();
  EXPECT_EQ(granted.at("approver").count(topic::kApproval), 1u);
  EXPECT_EQ(granted.at("planner").count(topic::kApproval), 0u);
  EXPECT_EQ(granted.at("viewer").count(topic::kApproval), 0u);
  for (const char* role : {"viewer", "planner", "approver"})
    EXPECT_EQ(granted.at(role).count(topic::kEmergencyStop), 1u) << role;
  // Arming the robot again is the approver's; planning is not the viewer's.
  EXPECT_EQ(requiredRole(kindOf("resume")), Role::kApprover);
  EXPECT_EQ(requiredRole(kindOf("reset_emergency")), Role::kApprover);
  EXPECT_EQ(requiredRole(kindOf("add_target")), Role::kPlanner);
  EXPECT_EQ(requiredRole(kindOf("query")), Role::kViewer);
  EXPECT_EQ(requiredRole(kindOf("emergency_stop")), Role::kViewer);
}

TEST(Roles, ACertificateSubjectReadsAsThePermissionsGrantNamesIt) {
  // A certificate made here with openssl; its subject as openssl prints it (RFC 2253).
  const std::string dir = ::testing::TempDir() + "/ignav_cert_test";
  const std::string cmd = "mkdir -p " + dir +
                          " && openssl req -x509 -newkey ec -pkeyopt "
                          "ec_paramgen_curve:prime256v1 -nodes -keyout " +
                          dir + "/k.pem -out " + dir +
                          "/c.pem -days 1 -subj "
                          "'/C=NL/O=ignav test/CN=dr smith' 2>/dev/null && openssl x509 -in " +
                          dir + "/c.pem -noout -subject -nameopt RFC2253 > " + dir + "/s.txt";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream subject_file(dir + "/s.txt");
  std::string expected;
  std::getline(subject_file, expected);
  expected = expected.substr(expected.find('=') + 1);  // "subject=..."
  EXPECT_EQ(certificateSubject(readConfigFile(dir + "/c.pem")), expected);
  EXPECT_EQ(expected, "CN=dr smith,O=ignav test,C=NL");
  EXPECT_EQ(certificateSubject("not a certificate"), "");
}

}  // namespace
}  // namespace ignav::protocol
