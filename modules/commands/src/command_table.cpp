#include "ignav/commands/command_table.hpp"

#include <iterator>

namespace ignav::commands {

const char* toString(ClientRole role) {
  switch (role) {
    case ClientRole::kViewer:
      return "viewer";
    case ClientRole::kPlanner:
      return "planner";
    case ClientRole::kApprover:
      return "approver";
  }
  return "unknown";
}

const std::vector<InputSpec>& inputTable() {
  static const std::vector<InputSpec> rows(std::begin(detail::kInputRows),
                                           std::end(detail::kInputRows));
  return rows;
}

const InputSpec& specOf(InputKind kind) {
  return inputTable().at(static_cast<std::size_t>(kind));
}

const InputSpec* commandNamed(std::string_view name) {
  for (const auto& s : inputTable())
    if ((s.traits & kFromClients) && name == s.name) return &s;
  return nullptr;
}

const InputSpec* commandOfWireKind(std::int32_t wire_kind) {
  if (wire_kind == kNoWireKind) return nullptr;
  for (const auto& s : inputTable())
    if (s.wire_kind == wire_kind) return &s;
  return nullptr;
}

const char* toString(InputKind kind) {
  return specOf(kind).name;
}

bool isCommand(InputKind kind) {
  return (specOf(kind).traits & kFromClients) != 0;
}

bool isQuestion(InputKind kind) {
  return (specOf(kind).traits & kQuestion) != 0;
}

bool needsControllerReading(InputKind kind) {
  return (specOf(kind).traits & kNeedsReading) != 0;
}

bool releasesMotion(InputKind kind) {
  return (specOf(kind).traits & kReleasesMotion) != 0;
}

bool isText(const Arguments& args) {
  return args.path_word != nullptr && std::string_view(args.path_word) == "TEXT";
}

std::string usageOf(const InputSpec& spec) {
  const Arguments& a = spec.args;
  std::string out;
  auto add = [&](const std::string& word) { out += (out.empty() ? "" : " ") + word; };
  const bool text_last = isText(a);  // words for a person take what the others leave
  if (a.path_is && !text_last) {
    add(a.path_choices ? a.path_choices : a.path_word ? a.path_word : "PATH");
  }
  auto repeated = [&](std::size_t n, const char* one) {
    if (n == kAnyCount) {
      add(std::string(one) + "...");
    } else {
      for (std::size_t i = 0; i < n; ++i)
        add(one);
    }
  };
  repeated(a.ids, "ID");
  repeated(a.points, "X,Y,Z");
  if (a.matrix_is) add(a.matrix_optional ? "[M11,M12,...,M44]" : "M11,M12,...,M44");
  if (text_last) add("TEXT...");
  return out;
}

}  // namespace ignav::commands
