#include "command_words.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "ignavctl.hpp"

namespace ignav::ctl {
namespace {

// The friendlier spellings people type, and the commands they send. They carry only the words:
// what follows them is read by the command's row, so that none can fall behind the table. A
// group's subcommand (table_commands.cpp, verify.cpp) takes every verb listed for it here.
struct Alias {
  const char* words;    // typed before the arguments: the subcommand, then its verb if any
  const char* command;  // the command sent: a row of the table
};
constexpr Alias kAliases[] = {
    {"load", "load_volume"},  // `load phantom` is the built-in phantom (phantom:)
    {"ready", "check_ready"},
    {"set-registration", "set_registration"},
    {"fiducials auto", "auto_fiducials"},  // waits for the detection's outcome
    {"fiducials set", "set_fiducials"},
    {"targets add", "add_target"},
    {"targets rm", "remove_target"},
    {"targets clear", "clear_targets"},
    {"targets lock", "lock_plan"},
    {"targets unlock", "unlock_plan"},
    {"targets pause", "pause_at"},               // stop part-way: MM (or none) ID
    {"targets override", "override_clearance"},  // ID REASON...
    {"targets propose", "propose_targets"},      // STRUCTURE SPACING_MM; waits for the outcome
    {"targets seeds", "plan_seeds"},  // STRUCTURE [model=..] [rx=..] [strength=..] [spacing=..]
    {"targets accept", "accept_proposals"},  // [ID...]: none, all of them
    {"targets dose", "compute_dose"},        // STRUCTURE [model=..] [rx=..] [strength=..]; waits
    {"structures load", "load_structures"},
    {"structures role", "structure_role"},  // NAME ROLE [MARGIN_MM]
    {"structures place", "place_robot"},    // STRUCTURE [from SIDE]; waits for the outcome
    {"verify load", "load_confirmation"},   // waits for the measurement; `same-frame`
    {"verify place", "place_seed"},
    {"verify accept", "accept_seed"},
    {"verify reject", "reject_seed"},
    {"verify fit", "fit_tissue"},
    {"verify aim", "use_tissue"},
    {"verify discard", "discard_tissue"},
    {"verify scan", "scan_needle"},  // waits for the search and the re-aim; `same-frame`
    {"verify reaim", "reaim"},
};

const commands::InputSpec& rowOf(const Alias& alias) {
  const commands::InputSpec* row = commands::commandNamed(alias.command);
  // A command renamed in the table: the alias is wrong, whatever is typed.
  if (!row) {
    throw std::logic_error(std::string("the alias '") + alias.words + "' sends '" + alias.command +
                           "', which is no command of the table");
  }
  return *row;
}

std::string withUsage(const std::string& typed, const commands::InputSpec& row) {
  const std::string usage = commands::usageOf(row);
  return usage.empty() ? typed : typed + " " + usage;
}

}  // namespace

Eigen::Vector3d triple(const std::string& text) {
  Eigen::Vector3d p;
  char extra = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &p.x(), &p.y(), &p.z(), &extra) != 3 ||
      !p.allFinite()) {
    throw UsageError("'" + text + "' is not X,Y,Z");
  }
  return p;
}

Eigen::Matrix4d matrix16(const std::string& text) {
  Eigen::Matrix4d m;
  std::stringstream in(text);
  std::string item;
  int k = 0;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (k >= 16 || end == item.c_str() || *end != '\0' || !std::isfinite(v)) {
      throw UsageError("'" + text + "' is not 16 comma-separated numbers");
    }
    m(k / 4, k % 4) = v;
    ++k;
  }
  if (k != 16) throw UsageError("'" + text + "' is not 16 comma-separated numbers");
  return m;
}

protocol::CommandArgs commandArgs(const commands::InputSpec& spec,
                                  const std::vector<std::string>& words, const std::string& typed) {
  const auto& a = spec.args;
  const std::string usage = withUsage(typed, spec);
  protocol::CommandArgs out;
  std::size_t next = 0;
  auto take = [&]() -> const std::string& {
    if (next >= words.size()) throw UsageError("usage: " + usage);
    return words[next++];
  };
  const bool text_last = commands::isText(a);
  if (a.path_is && !text_last) out.path = take();
  auto count = [&](std::size_t n, std::size_t others) {
    // "Any number" takes what the fields after it leave.
    return n == commands::kAnyCount ? words.size() - std::min(words.size(), next + others) : n;
  };
  const std::size_t matrix_words = a.matrix_is && !a.matrix_optional ? 1 : 0;
  const std::size_t after_ids = (a.points == commands::kAnyCount ? 0 : a.points) + matrix_words;
  for (std::size_t i = 0, n = count(a.ids, after_ids); i < n; ++i) {
    const std::string& word = take();
    try {
      std::size_t used = 0;
      const unsigned long id = std::stoul(word, &used);
      if (used != word.size() || id > UINT32_MAX) throw std::out_of_range(word);
      out.ids.push_back(static_cast<std::uint32_t>(id));
    } catch (const std::logic_error&) {
      throw UsageError("'" + word + "' is not a target id; usage: " + usage);
    }
  }
  for (std::size_t i = 0, n = count(a.points, matrix_words); i < n; ++i)
    out.points.push_back(triple(take()));
  if (a.matrix_is && (!a.matrix_optional || next < words.size())) out.matrix = matrix16(take());
  if (text_last) {
    if (next >= words.size()) throw UsageError("usage: " + usage);
    for (; next < words.size(); ++next)
      out.path += (out.path.empty() ? "" : " ") + words[next];
  }
  if (next != words.size()) throw UsageError("too many arguments; usage: " + usage);
  return out;
}

AliasCall aliasCall(const std::string& group, const std::vector<std::string>& words,
                    const std::string& usage) {
  for (const Alias& alias : kAliases) {
    const std::string typed = alias.words;
    if (typed == group) return AliasCall{rowOf(alias), commandArgs(rowOf(alias), words, typed)};
    if (!words.empty() && typed == group + " " + words.front()) {
      const std::vector<std::string> rest(words.begin() + 1, words.end());
      return AliasCall{rowOf(alias), commandArgs(rowOf(alias), rest, typed)};
    }
  }
  throw UsageError(group + ": " + usage);
}

std::string aliasUsage(const std::string& group) {
  std::string out;
  const std::string prefix = group + " ";
  for (const Alias& alias : kAliases) {
    const std::string typed = alias.words;
    if (typed == group) return commands::usageOf(rowOf(alias));
    if (typed.rfind(prefix, 0) == 0)
      out += (out.empty() ? "" : " | ") + withUsage(typed.substr(prefix.size()), rowOf(alias));
  }
  return out;
}

}  // namespace ignav::ctl
