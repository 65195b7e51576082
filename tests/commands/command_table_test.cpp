// The command table (modules/commands): what a person reads of a row's arguments, and the lookups
// clients route by. The rows' order is checked when compiling (command_table.hpp).
#include "ignav/commands/command_table.hpp"

#include <gtest/gtest.h>

#include <set>

namespace ignav::commands {
namespace {

TEST(CommandTable, UsageNamesEachArgumentAsAPersonTypesIt) {
  EXPECT_EQ(usageOf(specOf(InputKind::kLoadVolume)), "PATH");
  EXPECT_EQ(usageOf(specOf(InputKind::kFitTissue)), "NAME");  // a name, not a file
  EXPECT_EQ(usageOf(specOf(InputKind::kUseTissue)), "NAME");
  EXPECT_EQ(usageOf(specOf(InputKind::kCheckReady)), "robot|targeting");
  EXPECT_EQ(usageOf(specOf(InputKind::kMoveTarget)), "ID X,Y,Z");
  EXPECT_EQ(usageOf(specOf(InputKind::kSetFiducials)), "X,Y,Z X,Y,Z X,Y,Z");
  EXPECT_EQ(usageOf(specOf(InputKind::kReorderTargets)), "ID...");
  EXPECT_EQ(usageOf(specOf(InputKind::kSetRegistration)), "M11,M12,...,M44");
  EXPECT_EQ(usageOf(specOf(InputKind::kLoadConfirmation)), "PATH [M11,M12,...,M44]");
  EXPECT_EQ(usageOf(specOf(InputKind::kLockPlan)), "");
}

TEST(CommandTable, CommandsAreFoundByNameAndWireKindAndServerInputsAreNot) {
  std::set<std::int32_t> wire_kinds;
  for (const auto& spec : inputTable()) {
    SCOPED_TRACE(spec.name);
    EXPECT_EQ(&specOf(spec.kind), &spec);
    EXPECT_STREQ(toString(spec.kind), spec.name);
    if (isCommand(spec.kind)) {
      EXPECT_EQ(commandNamed(spec.name), &spec);
    } else {
      EXPECT_EQ(commandNamed(spec.name), nullptr) << "a client could send the server's own input";
      EXPECT_EQ(spec.wire_kind, kNoWireKind);
    }
    if (spec.wire_kind != kNoWireKind) {
      EXPECT_TRUE(wire_kinds.insert(spec.wire_kind).second) << "wire kind used twice";
      EXPECT_EQ(commandOfWireKind(spec.wire_kind), &spec);
    }
  }
  // The wire kinds of the IDL's enum from before the table (issue 22) keep their numbers.
  EXPECT_EQ(commandNamed("load_volume")->wire_kind, 0);
  EXPECT_EQ(commandNamed("check_ready")->wire_kind, 19);
  EXPECT_EQ(commandNamed("approve")->wire_kind, kNoWireKind);  // a topic of its own
  EXPECT_EQ(commandOfWireKind(kNoWireKind), nullptr);
  EXPECT_EQ(commandOfWireKind(9999), nullptr);
  EXPECT_EQ(commandNamed("volume_loaded"), nullptr);
}

}  // namespace
}  // namespace ignav::commands
