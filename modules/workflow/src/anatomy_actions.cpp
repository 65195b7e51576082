// The rows' actions for the patient's structures (issue 41; actions.hpp): loading them, giving
// them roles, and an operator's override of one target's clearance.
#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

#include <fmt/format.h>

#include "actions.hpp"
#include "ignav/dosimetry/seed_plan.hpp"
#include "ignav/workflow/background_jobs.hpp"
#include "session_rules.hpp"

namespace ignav::workflow::detail {
namespace {

using anatomy::kMaxMargin_mm;

// The whole word as a finite number; none for anything else ("", "5mm", "nan").
std::optional<double> finiteNumber(const std::string& word) {
  char* end = nullptr;
  const double number = std::strtod(word.c_str(), &end);
  if (word.empty() || *end != '\0' || !std::isfinite(number)) return std::nullopt;
  return number;
}

std::string names(const anatomy::StructureSet& set) {
  std::string out;
  for (const auto& s : set.structures)
    out += (out.empty() ? "" : ", ") + s.name;
  return out;
}

}  // namespace

Refusal startStructureLoad(Session& s, const Input& in, ActionOutput& out) {
  if (!s.ct.volume) {
    return Rejection{ReplyCode::kNoVolume, "no CT is loaded: structures are loaded on one"};
  }
  if (s.structures.loading != 0) {
    return Rejection{ReplyCode::kBusy, fmt::format("structures are loading ({}; load #{})",
                                                   s.structures.source, s.structures.loading)};
  }
  s.structures.loading = s.revision + 1;  // this step's
  s.structures.status = "loading";
  s.structures.message = fmt::format(
      "loading {} on the CT ({}){}", in.path, s.ct.source,
      s.structures.loaded.set ? "; the structures from before stay in use until then" : "");
  out.effects.start_jobs.push_back(JobKind::kStructureLoad);
  out.effects.structures_changed = true;
  out.note = fmt::format(
      "structure load #{} started ({}): StructuresState shows loading, then the structures or why "
      "they were refused",
      s.structures.loading, in.path);
  s.structures.source = in.path;
  return std::nullopt;
}

Refusal adoptStructures(Session& s, const Input& in, ActionOutput& out) {
  auto& st = s.structures;
  st.loading = 0;
  st.loaded = in.structures;
  st.roles.clear();
  for (const auto& structure : st.loaded.set->structures)
    st.roles.push_back({structure.role, structure.margin_mm});
  st.status = "loaded";
  st.source = in.path;
  st.message = in.summary;
  s.proposals = {};        // proposed in the structures before (one under way is ignored)
  s.dose = {};             // judged on them
  s.robot_placement = {};  // placed for them likewise
  out.effects.structures_changed = true;
  evaluateAll(s, out.effects);
  out.note = "structures loaded: " + in.summary;
  return std::nullopt;
}

Refusal noteStructureLoadFailure(Session& s, const Input& in, ActionOutput& out) {
  auto& st = s.structures;
  st.loading = 0;
  if (st.loaded.set) {
    st.status = "loaded";
    st.message = fmt::format("{} was refused ({}); the structures from {} stay", in.path, in.error,
                             st.loaded.set->source);
    st.source = st.loaded.set->source;
  } else {
    st.status = "failed";
    st.message = in.error;
  }
  out.effects.structures_changed = true;
  out.note = in.error;
  return std::nullopt;
}

Refusal setStructureRole(Session& s, const Input& in, ActionOutput& out) {
  auto& st = s.structures;
  if (!st.loaded.set) {
    return Rejection{ReplyCode::kNoStructures, "no structures are loaded (load_structures)"};
  }
  // NAME ROLE [MARGIN_MM], the name possibly of several words: read from the end.
  std::vector<std::string> words;
  std::istringstream text(in.path);
  for (std::string w; text >> w;)
    words.push_back(w);
  auto bad = [&](const std::string& why) {
    return Rejection{ReplyCode::kBadRole,
                     fmt::format("'{}': {} (NAME ROLE [MARGIN_MM])", in.path, why)};
  };
  std::optional<double> margin;
  if (!words.empty()) {
    char* end = nullptr;
    const double m = std::strtod(words.back().c_str(), &end);
    if (end != words.back().c_str() && *end == '\0') {
      if (!std::isfinite(m) || m < 0.0 || m > kMaxMargin_mm) {
        return bad(
            fmt::format("a margin of {} mm is outside 0-{:g} mm", words.back(), kMaxMargin_mm));
      }
      margin = m;
      words.pop_back();
    }
  }
  if (words.size() < 2) return bad("a name and a role are needed");
  const auto role = anatomy::roleNamed(words.back());
  if (!role) return bad("role '" + words.back() + "' is none of target, avoid, shown");
  words.pop_back();
  std::string name;
  for (const auto& w : words)
    name += (name.empty() ? "" : " ") + w;
  const auto& set = *st.loaded.set;
  const auto* structure = set.find(name);
  if (!structure) {
    return Rejection{ReplyCode::kUnknownStructure,
                     fmt::format("no structure '{}' (loaded: {})", name, names(set))};
  }
  if (*role == anatomy::Role::kAvoid && !margin) return bad("avoid needs a margin in mm");
  if (*role != anatomy::Role::kAvoid && margin) return bad("only avoid takes a margin");
  auto& choice = st.roles.at(static_cast<std::size_t>(structure - set.structures.data()));
  choice = {*role, margin.value_or(0.0)};
  out.effects.structures_changed = true;
  evaluateAll(s, out.effects);
  out.note = fmt::format("'{}' is now {}{}", structure->name, anatomy::toString(*role),
                         margin ? fmt::format(" with a margin of {:g} mm", *margin) : "");
  return std::nullopt;
}

Refusal overrideClearance(Session& s, const Input& in, ActionOutput& out) {
  Target* t = findTarget(s, in.ids[0]);
  if (!t) return Rejection{ReplyCode::kUnknownTarget, fmt::format("no target {}", in.ids[0])};
  const auto first = in.path.find_first_not_of(" \t");
  if (first == std::string::npos) {
    return Rejection{ReplyCode::kNoReason,
                     fmt::format("target {}: say why its path may pass so close", t->id)};
  }
  if (t->clearance_refusal.empty()) {
    return Rejection{ReplyCode::kNotTooClose,
                     fmt::format("target {} keeps every margin: nothing to override", t->id)};
  }
  t->clearance_override = in.path.substr(first);
  evaluate(s, *t);
  out.effects.targets_changed.push_back(t->id);
  out.note = t->message;
  return std::nullopt;
}

namespace {

// What any proposal needs: structures, a registration, none under way.
Refusal canPropose(const Session& s) {
  if (!s.structures.loaded.set) {
    return Rejection{ReplyCode::kNoStructures, "no structures are loaded (load_structures)"};
  }
  if (!s.registration) {
    return Rejection{ReplyCode::kNotRegistered,
                     "the CT is not registered: targets are proposed where the robot reaches"};
  }
  if (s.proposals.proposing != 0) {
    return Rejection{ReplyCode::kBusy,
                     fmt::format("targets are being proposed (#{})", s.proposals.proposing)};
  }
  return std::nullopt;
}

Refusal unknownStructure(const Session& s, const std::string& name) {
  return Rejection{ReplyCode::kUnknownStructure, fmt::format("no structure '{}' (loaded: {})", name,
                                                             names(*s.structures.loaded.set))};
}

// Starts the proposal's job on `structure` (a seed plan's when `seed_plan` is set).
void beginProposal(Session& s, const anatomy::Structure& structure, double spacing_mm,
                   std::optional<SeedPlanAsk> seed_plan, std::string message, ActionOutput& out) {
  auto& p = s.proposals;
  p.proposing = s.revision + 1;  // this step's
  p.status = "proposing";
  p.structure = structure.name;
  p.spacing_mm = spacing_mm;
  p.seed_plan = std::move(seed_plan);
  p.message = std::move(message);
  p.targets.clear();
  out.effects.start_jobs.push_back(JobKind::kTargetProposal);
  out.effects.structures_changed = true;
}

}  // namespace

Refusal startTargetProposal(Session& s, const Input& in, ActionOutput& out) {
  if (auto refused = canPropose(s)) return refused;
  // STRUCTURE SPACING_MM, the name possibly of several words: the spacing is the last.
  const auto last = in.path.find_last_of(" \t");
  const auto bad = [&](const std::string& why) {
    return Rejection{ReplyCode::kBadSpacing,
                     fmt::format("'{}': {} (STRUCTURE SPACING_MM)", in.path, why)};
  };
  if (last == std::string::npos) return bad("a structure and a spacing are needed");
  const std::string word = in.path.substr(last + 1);
  const auto parsed = finiteNumber(word);
  if (!parsed) return bad("'" + word + "' is not a spacing in mm");
  const double spacing = *parsed;
  if (spacing < kMinProposalSpacing_mm || spacing > kMaxProposalSpacing_mm) {
    return bad(fmt::format("a spacing of {:g} mm is outside {:g}-{:g} mm", spacing,
                           kMinProposalSpacing_mm, kMaxProposalSpacing_mm));
  }
  std::string name = in.path.substr(0, last);
  name.erase(name.find_last_not_of(" \t") + 1);
  name.erase(0, name.find_first_not_of(" \t"));
  const auto* structure = s.structures.loaded.set->find(name);
  if (!structure) return unknownStructure(s, name);
  beginProposal(
      s, *structure, spacing, std::nullopt,
      fmt::format("proposing targets that fill '{}' at {:g} mm", structure->name, spacing), out);
  out.note = fmt::format(
      "target proposal #{} started ('{}', {:g} mm): StructuresState shows the targets proposed, "
      "or why none are",
      s.proposals.proposing, structure->name, spacing);
  return std::nullopt;
}

Refusal readSeedWords(const Session& s, const std::string& text, bool planning, SeedWords& out) {
  if (!s.site || !s.site->dosimetry) {
    return Rejection{ReplyCode::kUnknownSeedModel,
                     "no seed models: the site file (server.yaml site:) has no dosimetry: block"};
  }
  const auto& site = *s.site->dosimetry;
  // The site's defaults, or for a dose the seed plan's.
  out.ask = planning || !s.dose.seeds
                ? SeedPlanAsk{site.seed_model, "", site.prescription_Gy, site.strength_U, true}
                : *s.dose.seeds;
  out.spacing_mm = site.spacing_mm;
  out.structure.clear();
  SeedPlanAsk& ask = out.ask;
  const char* usage = planning ? "STRUCTURE [model=NAME] [rx=GY] [strength=U] [spacing=MM] "
                                 "[implanted=none]"
                               : "STRUCTURE [model=NAME] [rx=GY] [strength=U]";
  const auto bad = [&](const std::string& why) {
    return Rejection{ReplyCode::kBadSeedPlan, fmt::format("'{}': {} ({})", text, why, usage)};
  };
  std::istringstream words(text);
  for (std::string word; words >> word;) {
    const auto eq = word.find('=');
    if (eq == std::string::npos) {
      out.structure += (out.structure.empty() ? "" : " ") + word;
      continue;
    }
    const std::string key = word.substr(0, eq), value = word.substr(eq + 1);
    if (key == "model") {
      ask.seed_model = value;
      continue;
    }
    if (key == "implanted" && planning) {
      if (value != "none" && value != "confirmation")
        return bad("implanted='" + value + "' is neither confirmation nor none");
      ask.implanted = value == "confirmation";
      continue;
    }
    const auto parsed = finiteNumber(value);
    if (!parsed) return bad(fmt::format("{} '{}' is not a number", key, value));
    const double number = *parsed;
    if (key == "rx")
      ask.prescription_Gy = number;
    else if (key == "strength")
      ask.strength_U = number;
    else if (key == "spacing" && planning)
      out.spacing_mm = number;
    else
      return bad(planning ? "'" + key + "' is none of model, rx, strength, spacing, implanted"
                          : "'" + key + "' is none of model, rx, strength");
  }
  if (out.structure.empty() && planning) return bad("a structure to cover is needed");
  if (!(ask.prescription_Gy > 0.0 && ask.prescription_Gy <= 1000.0))
    return bad(fmt::format("a prescription of {:g} Gy is outside 0-1000 Gy", ask.prescription_Gy));
  if (!(ask.strength_U >= dosimetry::kMinSeedStrength_U &&
        ask.strength_U <= dosimetry::kMaxSeedStrength_U))
    return bad(fmt::format("a seed strength of {:g} U is outside {:g}-{:g} U", ask.strength_U,
                           dosimetry::kMinSeedStrength_U, dosimetry::kMaxSeedStrength_U));
  if (!(out.spacing_mm >= anatomy::kMinSeedSpacing_mm &&
        out.spacing_mm <= anatomy::kMaxSeedSpacing_mm))
    return bad(fmt::format("a spacing of {:g} mm is outside {:g}-{:g} mm", out.spacing_mm,
                           anatomy::kMinSeedSpacing_mm, anatomy::kMaxSeedSpacing_mm));
  if (std::find(site.seed_models.begin(), site.seed_models.end(), ask.seed_model) ==
      site.seed_models.end()) {
    return Rejection{ReplyCode::kUnknownSeedModel,
                     fmt::format("no seed model '{}' (the site's: {})", ask.seed_model,
                                 fmt::join(site.seed_models, ", "))};
  }
  ask.seed_model_path = site.seed_models_dir + "/" + ask.seed_model + ".yaml";
  if (out.structure.empty()) return std::nullopt;
  const auto* structure = s.structures.loaded.set->find(out.structure);
  if (!structure) return unknownStructure(s, out.structure);
  out.structure = structure->name;
  const auto index =
      static_cast<std::size_t>(structure - s.structures.loaded.set->structures.data());
  if (s.structures.roles.at(index).role != anatomy::Role::kTarget)
    return bad(fmt::format("'{}' is not a target (structure_role gives it one)", structure->name));
  return std::nullopt;
}

Refusal startSeedPlan(Session& s, const Input& in, ActionOutput& out) {
  if (auto refused = canPropose(s)) return refused;
  SeedWords words;
  if (auto refused = readSeedWords(s, in.path, true, words)) return refused;
  const SeedPlanAsk& ask = words.ask;
  const double spacing = words.spacing_mm;
  const auto* structure = s.structures.loaded.set->find(words.structure);
  const std::string what =
      fmt::format("planning seeds of {} at {:g} U for {:g} Gy to '{}' (candidates {:g} mm apart)",
                  ask.seed_model, ask.strength_U, ask.prescription_Gy, structure->name, spacing);
  beginProposal(s, *structure, spacing, ask, what, out);
  out.note = fmt::format(
      "seed plan #{} started: {}; StructuresState shows the seeds proposed, "
      "or why none are",
      s.proposals.proposing, what);
  return std::nullopt;
}

namespace {

// The proposal's outcome: its points (none when it failed) and what it said.
Refusal endProposal(Session& s, const char* status, const std::string& message,
                    const std::vector<Eigen::Vector3d>& points, ActionOutput& out) {
  auto& p = s.proposals;
  p.proposing = 0;
  p.status = status;
  p.message = message;
  p.targets.clear();
  for (const auto& lps : points)
    p.targets.push_back({static_cast<std::uint32_t>(p.targets.size() + 1), lps});
  out.effects.structures_changed = true;
  out.note = message;
  return std::nullopt;
}

}  // namespace

Refusal adoptProposals(Session& s, const Input& in, ActionOutput& out) {
  return endProposal(s, "proposed", in.summary, in.points, out);
}

Refusal noteProposalFailure(Session& s, const Input& in, ActionOutput& out) {
  return endProposal(s, "failed", in.error, {}, out);
}

Refusal acceptProposals(Session& s, const Input& in, ActionOutput& out) {
  auto& p = s.proposals;
  if (p.targets.empty()) {
    return Rejection{ReplyCode::kNoProposals, p.proposing
                                                  ? "targets are still being proposed"
                                                  : "no targets are proposed (propose_targets)"};
  }
  std::vector<std::uint32_t> ids = in.ids;
  if (ids.empty()) {
    for (const auto& t : p.targets)
      ids.push_back(t.id);
  }
  std::vector<const ProposedTarget*> taken;
  for (const auto id : ids) {
    const auto it = std::find_if(p.targets.begin(), p.targets.end(),
                                 [&](const ProposedTarget& t) { return t.id == id; });
    if (it == p.targets.end()) {
      return Rejection{
          ReplyCode::kUnknownProposal,
          fmt::format("no proposed target {} ({} are proposed)", id, p.targets.size())};
    }
    if (std::find(taken.begin(), taken.end(), &*it) == taken.end()) taken.push_back(&*it);
  }
  if (s.targets.size() + taken.size() > s.policy.limits.max_targets) {
    return Rejection{
        ReplyCode::kTooManyTargets,
        fmt::format("{} more would make {} targets, more than one insertion takes "
                    "(planning.max_targets {})",
                    taken.size(), s.targets.size() + taken.size(), s.policy.limits.max_targets)};
  }
  // Judged again as they join: the session may have changed since they were proposed.
  std::string added;
  std::size_t not_plannable = 0;
  for (const ProposedTarget* proposed : taken) {
    Target t;
    t.id = s.next_target_id++;
    t.lps_mm = proposed->lps_mm;
    evaluate(s, t);
    not_plannable += t.plannable() ? 0 : 1;
    added += fmt::format("{}{} (proposed {})", added.empty() ? "" : ", ", t.id, proposed->id);
    out.effects.targets_changed.push_back(t.id);
    s.targets.push_back(std::move(t));
  }
  std::vector<ProposedTarget> left;
  for (const auto& t : p.targets)
    if (std::find(taken.begin(), taken.end(), &t) == taken.end()) left.push_back(t);
  p.targets = std::move(left);
  out.effects.structures_changed = true;
  if (p.seed_plan) {  // the targets are seeds: their dose, planned
    s.dose.seeds = *p.seed_plan;
    s.dose.structure = p.structure;
    recomputeDose(s, in, "a seed plan accepted", out);
  }
  out.note = fmt::format("targets {} added{}; {} still proposed", added,
                         not_plannable ? fmt::format(" ({} of them no longer plannable: see "
                                                     "their messages)",
                                                     not_plannable)
                                       : "",
                         p.targets.size());
  return std::nullopt;
}

}  // namespace ignav::workflow::detail
