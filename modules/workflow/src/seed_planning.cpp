// plan_seeds' job (background_jobs.hpp): the candidates propose_targets would keep, then the
// fewest seeds among them whose dose covers the structure and spares the avoided ones.
#include <fmt/format.h>

#include <cmath>
#include <map>

#include "ignav/dosimetry/seed_plan.hpp"
#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/reducer.hpp"
#include "proposal_lattice.hpp"

namespace ignav::workflow {

dosimetry::DoseStructure doseStructure(const anatomy::Structure& s) {
  dosimetry::DoseStructure out;
  out.name = s.name;
  const auto& m = s.mask;
  const auto& d = m.geometry.dims;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i)
        if (m.inside[m.index(i, j, k)])
          out.voxels_lps_mm.push_back(m.geometry.toLps(Eigen::Vector3d(i, j, k)));
  out.voxel_cm3 = m.volume_cm3() / static_cast<double>(std::max<std::size_t>(1, m.count()));
  return out;
}

dosimetry::Seed seedAt(const Session& s, const Target& t) {
  const auto path = needlePathLps(s, t.commandedJoints());
  dosimetry::Seed seed;
  seed.centre_lps_mm = t.lps_mm;
  if (path.size() >= 2) {
    const Eigen::Vector3d step = path.back() - path[path.size() - 2];
    if (step.norm() > 1e-9) seed.axis_lps = step.normalized();
  }
  return seed;
}

std::vector<dosimetry::Seed> implantedSeeds(const Session& s) {
  std::vector<dosimetry::Seed> out;
  const auto& c = s.confirmation;
  if (!c.registration || !s.registration) return out;
  const auto& planning = *s.registration;
  const Eigen::Vector3d axis =
      (planning.toImage(Eigen::Vector3d::UnitZ()) - planning.toImage(Eigen::Vector3d::Zero()))
          .normalized();
  for (const auto& seed : c.seeds) {
    if (seed.kind != "seed" || seed.rejected) continue;
    out.push_back({planning.toImage(c.registration->registration.toRobot(seed.lps_mm)), axis});
  }
  return out;
}

Expected<dosimetry::SeedPlanRequest> doseRequest(const Session& s, const SeedPlanAsk& ask,
                                                 const anatomy::Structure& target) {
  const auto model = dosimetry::readSeedModel(ask.seed_model_path);
  if (!model) {
    return makeError(model.error().code,
                     fmt::format("seed model '{}': {}", ask.seed_model, model.error().message),
                     model.error().reason);
  }
  auto table = dosimetry::DoseRateTable::make(*model);
  if (!table) return table.error();
  dosimetry::SeedPlanRequest request;
  request.table = std::make_shared<const dosimetry::DoseRateTable>(std::move(*table));
  request.strength_U = ask.strength_U;
  request.prescription_Gy = ask.prescription_Gy;
  request.target = doseStructure(target);
  const auto* set = s.structures.loaded.set.get();
  for (std::size_t n = 0; set && n < set->structures.size(); ++n) {
    const auto& st = set->structures[n];
    if (s.structures.roles.at(n).role != anatomy::Role::kAvoid) continue;
    const anatomy::SiteRole* role = s.site ? s.site->roleFor(st.name) : nullptr;
    request.organs.push_back(
        {doseStructure(st), role ? role->dose_limits : dosimetry::OrganLimits{}});
  }
  return request;
}

namespace {

std::string lps(const Eigen::Vector3d& p) {
  return fmt::format("({:.1f}, {:.1f}, {:.1f})", p.x(), p.y(), p.z());
}

// Planned against delivered, and where the delivered dose is cold: the start of a re-plan's
// message.
std::string deliveredText(const Session& s, dosimetry::SeedPlanRequest request) {
  const auto delivered = std::move(request.implanted);
  request.implanted.clear();
  std::vector<dosimetry::Seed> planned;
  for (const auto& t : s.targets)
    planned.push_back(seedAt(s, t));
  const auto as_planned = dosimetry::evaluatePlan(request, planned);
  const auto as_delivered = dosimetry::evaluatePlan(request, delivered);
  const auto cold = dosimetry::coldSpots(request, delivered);
  if (!as_planned || !as_delivered || !cold) return "";
  std::string spots;
  for (std::size_t n = 0; n < std::min<std::size_t>(3, cold->size()); ++n)
    spots +=
        fmt::format("{}{:.2f} cm³ at {} (down to {:.0f} Gy)", n ? ", " : "", (*cold)[n].volume_cm3,
                    lps((*cold)[n].centroid_lps_mm), (*cold)[n].min_dose_Gy);
  return fmt::format(
      "delivered by the {} seeds on the confirmation CT: {} (planned, the {} targets: {}); {} "
      "cold spot{}{}{}; ",
      delivered.size(), as_delivered->describe(), planned.size(), as_planned->describe(),
      cold->size(), cold->size() == 1 ? "" : "s", cold->empty() ? "" : ": ", spots);
}

// Progress in thousandths: judging the lattice, then the plan's stages in turn.
struct Progress {
  const JobContext& context;
  void operator()(std::size_t from, std::size_t to, std::size_t done, std::size_t total) const {
    if (!context.progress) return;
    const double f =
        total ? static_cast<double>(std::min(done, total)) / static_cast<double>(total) : 0.0;
    context.progress(from + static_cast<std::size_t>(f * static_cast<double>(to - from)), 1000);
  }
};

std::string organLine(const dosimetry::OrganResult& o) {
  const auto& m = o.metrics;
  return fmt::format("{} D10 {:.0f} %, D2cc {:.1f} Gy, V100 {:.2f} cm³", o.name, m.d10_percent,
                     m.d2cc_Gy, m.v100_cm3);
}

}  // namespace

Input planSeedTargets(std::uint64_t job, const std::string& structure, double spacing_mm,
                      const SeedPlanAsk& ask, const std::shared_ptr<const Session>& snapshot,
                      const JobContext& context) {
  const Session& s = *snapshot;
  auto [in, target] = startProposal(job, structure, spacing_mm, s);
  if (!target) return in;
  const Progress progress{context};

  const auto lattice = latticeIn(target->mask, *s.registration, spacing_mm);
  if (!lattice) {
    in.error = fmt::format("a {:g} mm lattice puts more than {} points in '{}': a coarser spacing",
                           spacing_mm, kMaxProposalCandidates, target->name);
    return in;
  }
  const Judged judged = judge(
      s, *lattice, [&](std::size_t done, std::size_t total) { progress(0, 400, done, total); });
  if (judged.kept.empty()) {
    in.error = fmt::format(
        "none of the {} lattice points {:g} mm apart in '{}' is reachable with "
        "every clearance kept{}",
        lattice->size(), spacing_mm, target->name,
        judged.left_out.empty() ? "" : ": " + judged.left_out);
    return in;
  }

  auto asked = doseRequest(s, ask, *target);
  if (!asked) {
    in.error = asked.error().message;
    return in;
  }
  dosimetry::SeedPlanRequest request = std::move(asked).value();
  for (const auto& t : judged.kept)
    request.candidates.push_back(seedAt(s, t));
  const std::size_t room = s.policy.limits.max_targets > s.targets.size()
                               ? s.policy.limits.max_targets - s.targets.size()
                               : 0;
  request.max_seeds = std::max<std::size_t>(room, 1);
  if (ask.implanted) request.implanted = implantedSeeds(s);
  const std::string delivered = request.implanted.empty() ? "" : deliveredText(s, request);

  const std::map<std::string_view, std::pair<std::size_t, std::size_t>> stages = {
      {"dose per candidate", {400, 550}},
      {"linear programme", {550, 650}},
      {"repair", {650, 900}},
      {"every voxel", {900, 950}}};
  const auto plan = dosimetry::planSeeds(
      request, [&](std::size_t done, std::size_t total, std::string_view stage) {
        const auto found = stages.find(stage);
        if (found != stages.end()) progress(found->second.first, found->second.second, done, total);
      });
  const std::string candidates = fmt::format(
      "{} of the {} lattice points {:g} mm apart in '{}' are reachable with every clearance kept",
      judged.kept.size(), lattice->size(), spacing_mm, target->name);
  if (!plan) {
    in.error = fmt::format("{}; {}", plan.error().message, candidates);
    return in;
  }
  progress(0, 1000, 1, 1);

  std::vector<Target> chosen;
  for (const std::size_t j : plan->chosen)
    chosen.push_back(judged.kept[j]);
  in.points = visitOrder(s, chosen).points;
  const auto& e = plan->evaluation;
  std::string organs;
  for (const auto& o : e.organs)
    organs += "; " + organLine(o);
  in.summary = fmt::format(
      "{}seed plan: {} seeds {}of {} at {:g} U for {:g} Gy to '{}' ({:.1f} cm³): V100 {:.1f} %, "
      "D90 {:.1f} %, V150 {:.1f} %{}; {}",
      delivered, chosen.size(), request.implanted.empty() ? "" : "to add ", ask.seed_model,
      ask.strength_U, ask.prescription_Gy, target->name, e.target_cm3, 100.0 * e.target.v100,
      e.target.d90_percent, 100.0 * e.target.v150, organs, candidates);
  if (!plan->raised_limits.empty())
    in.summary +=
        fmt::format("; limits the implanted seeds broke: {}", fmt::join(plan->raised_limits, "; "));
  if (request.implanted.empty()) {  // the usual baseline, for a first plan
    const auto uniform = dosimetry::uniformLoading(request);
    in.summary += "; uniform loading " +
                  (uniform ? fmt::format("({:g} mm apart) needs {} seeds: {}", uniform->spacing_mm,
                                         uniform->chosen.size(), uniform->evaluation.describe())
                           : "does not cover it: " + uniform.error().message);
  }
  in.kind = InputKind::kTargetsProposed;
  return in;
}

}  // namespace ignav::workflow
