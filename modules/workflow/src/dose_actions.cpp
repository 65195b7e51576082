// The seeds' dose (issue 42, part 5): compute_dose and the job's outcomes; accepting a seed plan
// and measuring a confirmation CT start it too (recomputeDose).
#include <fmt/format.h>

#include "actions.hpp"
#include "session_seeds.hpp"

namespace ignav::workflow::detail {

namespace {

// The session's seeds now: a seed at each plannable target, and the confirmation CT's.
void captureSeeds(const Session& s, std::vector<dosimetry::Seed>& planned,
                  std::vector<dosimetry::Seed>& delivered) {
  planned.clear();
  for (const auto& t : s.targets)
    if (t.plannable()) planned.push_back(seedAt(s, t));
  delivered = implantedSeeds(s);
}

}  // namespace

void recomputeDose(Session& s, const Input& in, const std::string& why, ActionOutput& out) {
  auto& d = s.dose;
  if (!d.seeds || d.structure.empty()) return;
  out.effects.structures_changed = true;
  captureSeeds(s, d.planned_seeds, d.delivered_seeds);
  if (d.planned_seeds.empty() && d.delivered_seeds.empty()) {
    d.computing = 0;
    d.status = "failed";
    d.computed.reset();
    d.message = "no seeds: no target is plannable, and no confirmation CT found any";
    return;
  }
  d.computing = s.revision + 1;  // this step's revision: the job names it
  d.asked_s = in.time_s;
  d.status = "computing";
  d.message = fmt::format("computing the dose of {} at {:g} U for {:g} Gy to '{}' ({})",
                          d.seeds->seed_model, d.seeds->strength_U, d.seeds->prescription_Gy,
                          d.structure, why);
  out.effects.start_jobs.push_back(JobKind::kDoseComputation);
}

Refusal startDoseComputation(Session& s, const Input& in, ActionOutput& out) {
  if (!s.structures.loaded.set) {
    return Rejection{ReplyCode::kNoStructures,
                     "no structures are loaded: the dose is judged on one (load_structures)"};
  }
  SeedWords words;
  if (auto refused = readSeedWords(s, in.path, false, words)) return refused;
  if (words.structure.empty()) words.structure = s.dose.structure;
  if (words.structure.empty()) {
    return Rejection{ReplyCode::kNoDoseToCompute,
                     "which structure is dosed? name one (compute_dose STRUCTURE): no seed plan "
                     "was accepted"};
  }
  std::vector<dosimetry::Seed> planned, delivered;
  captureSeeds(s, planned, delivered);
  if (planned.empty() && delivered.empty()) {
    return Rejection{ReplyCode::kNoDoseToCompute,
                     "no plannable targets, and no confirmation CT's seeds: nothing to dose"};
  }
  s.dose.seeds = words.ask;
  s.dose.structure = words.structure;
  recomputeDose(s, in, "asked", out);
  out.note = fmt::format("dose computation #{} started: {}; StructuresState shows its metrics",
                         s.dose.computing, s.dose.message);
  return std::nullopt;
}

Refusal adoptDose(Session& s, const Input& in, ActionOutput& out) {
  auto& d = s.dose;
  d.computing = 0;
  d.status = "computed";
  d.computed = in.dose;
  d.message = in.summary;
  if (in.dose && !in.dose->files.empty())
    d.message += fmt::format("; in the session folder: {}", fmt::join(in.dose->files, ", "));
  if (!in.error.empty()) d.message += "; not written: " + in.error;
  out.effects.structures_changed = true;
  out.note = d.message;
  return std::nullopt;
}

Refusal noteDoseFailure(Session& s, const Input& in, ActionOutput& out) {
  auto& d = s.dose;
  d.computing = 0;
  d.status = "failed";
  d.computed.reset();
  d.message = in.error;
  out.effects.structures_changed = true;
  out.note = in.error;
  return std::nullopt;
}

}  // namespace ignav::workflow::detail
