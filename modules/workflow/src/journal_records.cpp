#include "journal_records.hpp"

#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "ignav/workflow/background_jobs.hpp"
#include "ignav/workflow/reducer.hpp"

namespace ignav::workflow {
namespace {

// A structure's dose limits by their journal keys.
std::array<std::pair<const char*, double*>, 3> doseLimitFields(dosimetry::OrganLimits& l) {
  return {{{"d10_percent", &l.d10_percent},
           {"d2cc_percent", &l.d2cc_percent},
           {"dmax_percent", &l.dmax_percent}}};
}

using nlohmann::json;

json vec3(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}
json jointsJson(const kinematics::Joints& j) {
  return {j.theta_c_rad, j.z_c_mm, j.z_s_mm};
}

Eigen::Vector3d vec3From(const json& j, const char* field) {
  if (!j.is_array() || j.size() != 3) {
    throw std::invalid_argument(std::string(field) + ": not 3 numbers");
  }
  const Eigen::Vector3d p(j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>());
  if (!p.allFinite()) throw std::invalid_argument(std::string(field) + ": not finite");
  return p;
}
kinematics::Joints jointsFrom(const json& j, const char* field) {
  const Eigen::Vector3d v = vec3From(j, field);
  return {v.x(), v.y(), v.z()};
}

// needle_scanned's re-aim: what the job computed, so that replay never runs it again.
json reaimJson(const ReaimProposal& r) {
  json aims = json::array();
  for (const auto& a : r.aims) {
    aims.push_back({{"target", a.target_id},
                    {"how", a.how},
                    {"before", jointsJson(a.before)},
                    {"joints", jointsJson(a.joints)},
                    {"before_landing", vec3(a.before_landing_robot_mm)},
                    {"landing", vec3(a.landing_robot_mm)}});
  }
  return {{"target", r.target_id},
          {"source", r.source},
          {"paused", jointsJson(r.paused)},
          {"tip_lps", vec3(r.tip_lps_mm)},
          {"tip_robot", vec3(r.tip_robot_mm)},
          {"tip_offset_mm", r.tip_offset_mm},
          {"path_rms_mm", r.path_rms_mm},
          {"path_points", r.path_points},
          {"model", r.model},
          {"message", r.message},
          {"aims", aims}};
}

json coverageJson(const placement::Coverage& c) {
  return {{"samples", c.samples},
          {"covered", c.covered},
          {"unreachable", c.unreachable},
          {"too_close", c.too_close}};
}

json skinJson(const placement::SkinEntry& k) {
  return {{"entry_lps", vec3(k.entry_lps_mm)},
          {"skin_distance_mm", k.skin_distance_mm},
          {"seen", k.seen}};
}

json placedJson(const placement::PlacedPose& p) {
  json rotation = json::array();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      rotation.push_back(p.pose.rotation(r, c));
  return {{"origin_lps", vec3(p.pose.origin_lps_mm)},
          {"rotation", rotation},  // robot -> image, row-major
          {"coverage", coverageJson(p.coverage)},
          {"skin", skinJson(p.skin)},
          {"tilt_deg", p.tilt_deg},
          {"shift_mm", p.shift_mm}};
}

json journalRecord(const Input& in, const Session& after) {
  json points = json::array();
  for (const auto& p : in.points)
    points.push_back({p.x(), p.y(), p.z()});
  json record = {{"v", kJournalFormat},
                 {"t", in.time_s},
                 {"revision", after.revision},
                 {"input", toString(in.kind)},
                 {"phase", toString(after.phase)}};
  if (isCommand(in.kind)) {
    record["client_id"] = in.client_id;
    record["request_id"] = in.request_id;
    if (!in.role.empty()) record["role"] = in.role;
    if (!in.identity.empty()) record["identity"] = in.identity;
  }
  if (!in.path.empty()) record["path"] = in.path;
  if (!in.points.empty()) record["points"] = points;
  if (!in.ids.empty()) record["ids"] = in.ids;
  if (in.kind == InputKind::kVolumeLoaded && in.loaded.volume) {
    const auto& g = in.loaded.volume->geometry;
    record["source"] = in.loaded.source;
    record["description"] = in.loaded.description;
    record["dims"] = {g.dims[0], g.dims[1], g.dims[2]};
  }
  if (!in.seeds.empty()) {
    json seeds = json::array();
    for (const auto& s : in.seeds) {
      json seed = {{"id", s.id},
                   {"lps", {s.lps_mm.x(), s.lps_mm.y(), s.lps_mm.z()}},
                   {"length_mm", s.length_mm},
                   {"width_mm", s.width_mm}};
      if (s.kind != "seed") seed["kind"] = s.kind;
      if (!s.path_lps_mm.empty()) {
        json path = json::array();
        for (const auto& p : s.path_lps_mm)
          path.push_back({p.x(), p.y(), p.z()});
        seed["path_lps"] = path;
      }
      seeds.push_back(seed);
    }
    record["seeds"] = seeds;
  }
  if (in.reaim) record["reaim"] = reaimJson(*in.reaim);
  if (!in.placements.empty()) {
    json placed = json::array();
    for (const auto& p : in.placements)
      placed.push_back(placedJson(p));
    record["placements"] = placed;
  }
  if (in.mounted) {
    const auto& d = in.mounted->deviation;
    record["mounted"] = {{"entry_mm", d.entry_mm},
                         {"axis_deg", d.axis_deg},
                         {"depth_mm", d.depth_mm},
                         {"coverage", coverageJson(in.mounted->coverage)},
                         {"skin", skinJson(in.mounted->skin)}};
  }
  if (!in.error.empty()) record["error"] = in.error;
  if (in.job != 0) record["job"] = in.job;
  if (!in.summary.empty()) record["summary"] = in.summary;
  if (in.policy) {
    record["policy"] = {{"approvers", in.policy->approvers},
                        {"expiry_s", in.policy->expiry_s},
                        {"speed_steps_s", in.policy->speed_steps_s},
                        {"acceleration_steps_s2", in.policy->acceleration_steps_s2},
                        {"max_targets", in.policy->limits.max_targets},
                        {"max_total_rotation_rad", in.policy->limits.max_total_rotation_rad}};
  }
  if (in.site) {
    json roles = json::array();
    for (const auto& r : in.site->roles) {
      json entry = {{"name", r.name},
                    {"aliases", r.aliases},
                    {"role", anatomy::toString(r.role)},
                    {"margin_mm", r.margin_mm}};
      json limits = json::object();  // the finite ones (issue 42)
      dosimetry::OrganLimits dose_limits = r.dose_limits;
      for (const auto& [key, value] : doseLimitFields(dose_limits))
        if (std::isfinite(*value)) limits[key] = *value;
      if (!limits.empty()) entry["dose_limits"] = std::move(limits);
      roles.push_back(std::move(entry));
    }
    const auto& limits = in.site->placement;
    record["site"] = {{"name", in.site->name},
                      {"roles", roles},
                      {"placement",
                       {{"approach", limits.approach},
                        {"insertion_lps", vec3(limits.insertion_lps)},
                        {"max_tilt_deg", limits.max_tilt_deg},
                        {"max_shift_mm", limits.max_shift_mm},
                        {"min_skin_distance_mm", limits.min_skin_distance_mm},
                        {"skin_hu", limits.skin_hu}}}};
    if (const auto& d = in.site->dosimetry) {
      record["site"]["dosimetry"] = {
          {"seed_models_dir", d->seed_models_dir}, {"seed_models", d->seed_models},
          {"seed_model", d->seed_model},           {"prescription_Gy", d->prescription_Gy},
          {"strength_U", d->strength_U},           {"spacing_mm", d->spacing_mm}};
    }
  }
  if (in.tissue) {
    record["tissue"] = {{"name", in.tissue->name},
                        {"source", in.tissue->source},
                        {"lambda1", in.tissue->tissue.lambda1},
                        {"lambda2", in.tissue->tissue.lambda2},
                        {"curvature_per_mm", in.tissue->needle.curvature_per_mm},
                        {"wheelbase_mm", in.tissue->needle.wheelbase_mm}};
  }
  if (!in.robot_id.empty()) record["robot_id"] = in.robot_id;
  if (!in.session_uuid.empty()) record["session_uuid"] = in.session_uuid;
  if (in.plan_id != 0) record["plan_id"] = in.plan_id;
  if (!in.digest.empty()) record["digest"] = in.digest;
  if (in.matrix) {
    json m = json::array();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        m.push_back((*in.matrix)(r, c));
    record["matrix"] = m;  // row-major
  }
  if (in.controller) {
    const auto& c = *in.controller;
    record["controller"] = {
        {"state", actuation::toString(c.state)},
        {"position", c.position.motor},
        {"moving", c.moving},
        {"fault", c.fault},
    };
  }
  return record;
}

// An integer field of a journal record, checked: nlohmann's get<int>() of a float (1.8e22, say)
// is an out-of-range conversion, undefined behaviour (found by fuzz_journal).
template <typename Int>
Int integer(const json& v, const char* field) {
  static_assert(std::is_integral_v<Int>);
  bool fits = false;
  if (v.is_number_unsigned()) {
    fits = v.get<std::uint64_t>() <= static_cast<std::uint64_t>(std::numeric_limits<Int>::max());
  } else if (v.is_number_integer()) {
    const auto i = v.get<std::int64_t>();
    fits = std::is_signed_v<Int>
               ? i >= static_cast<std::int64_t>(std::numeric_limits<Int>::min()) &&
                     i <= static_cast<std::int64_t>(std::numeric_limits<Int>::max())
               : i >= 0 && static_cast<std::uint64_t>(i) <=
                               static_cast<std::uint64_t>(std::numeric_limits<Int>::max());
  }
  if (!fits)
    throw std::invalid_argument(std::string(field) + ": " + v.dump() +
                                " is not an integer in range");
  return v.get<Int>();
}

template <typename Int>
Int integer(const json& object, const char* field, Int fallback) {
  return object.contains(field) ? integer<Int>(object.at(field), field) : fallback;
}

placement::Coverage coverageFrom(const json& j) {
  placement::Coverage c;
  c.samples = integer<std::size_t>(j.at("samples"), "coverage.samples");
  c.covered = integer<std::size_t>(j.at("covered"), "coverage.covered");
  c.unreachable = integer<std::size_t>(j.at("unreachable"), "coverage.unreachable");
  for (const auto& n : j.at("too_close"))
    c.too_close.push_back(integer<std::size_t>(n, "coverage.too_close"));
  if (c.covered > c.samples) throw std::invalid_argument("coverage: more covered than samples");
  return c;
}

placement::SkinEntry skinFrom(const json& j) {
  placement::SkinEntry k;
  k.entry_lps_mm = vec3From(j.at("entry_lps"), "skin.entry_lps");
  k.skin_distance_mm = j.at("skin_distance_mm").get<double>();
  k.seen = j.at("seen").get<bool>();
  return k;
}

std::optional<actuation::ControllerStatus> readingFromJson(const json& j) {
  actuation::ControllerStatus c;
  const std::string state = j.at("state").get<std::string>();
  bool known = false;
  for (auto st : {actuation::ControllerState::kDisconnected, actuation::ControllerState::kIdle,
                  actuation::ControllerState::kMoving, actuation::ControllerState::kFault}) {
    if (state == actuation::toString(st)) {
      c.state = st;
      known = true;
    }
  }
  if (!known) throw std::invalid_argument("unknown controller state '" + state + "'");
  const json& position = j.at("position");
  if (!position.is_array() || position.size() != 3) {
    throw std::invalid_argument("controller.position: not 3 numbers");
  }
  for (std::size_t a = 0; a < 3; ++a)
    c.position.motor[a] = integer<std::int64_t>(position[a], "controller.position");
  c.moving = j.at("moving").get<std::array<bool, 3>>();
  c.fault = j.at("fault").get<std::string>();
  return c;
}

InputKind inputKindFromName(const std::string& name, bool& found) {
  for (const auto& spec : inputTable()) {
    if (name == spec.name) {
      found = true;
      return spec.kind;
    }
  }
  found = false;
  return InputKind::kQuery;
}

}  // namespace

namespace detail {

std::string journalLine(const Input& in, const Session& after) {
  return journalRecord(in, after).dump();
}

}  // namespace detail

Expected<JournalEntry> parseJournalRecord(const std::string& line) {
  const json r = json::parse(line, nullptr, /*allow_exceptions=*/false);
  auto bad = [](const std::string& why) { return makeError(ErrorCode::kFormat, why); };
  if (r.is_discarded() || !r.is_object()) return bad("not a JSON object");
  try {
    const int format = integer(r, "v", 0);
    if (format < kOldestJournalFormat || format > kJournalFormat) {
      return bad("format version " + r.value("v", json(0)).dump() + ", this build reads " +
                 std::to_string(kOldestJournalFormat) + " to " + std::to_string(kJournalFormat));
    }
    JournalEntry e;
    e.input.journal_format = format;
    bool known = false;
    e.input.kind = inputKindFromName(r.at("input").get<std::string>(), known);
    if (!known) return bad("unknown input '" + r.at("input").get<std::string>() + "'");
    e.input.time_s = r.at("t").get<double>();
    e.revision = integer<std::uint64_t>(r.at("revision"), "revision");
    e.phase = r.at("phase").get<std::string>();
    e.input.client_id = r.value("client_id", "");
    e.input.request_id = integer(r, "request_id", std::uint64_t{0});
    e.input.role = r.value("role", "");
    e.input.identity = r.value("identity", "");
    e.input.path = r.value("path", "");
    for (const auto& p : r.value("points", json::array())) {
      e.input.points.emplace_back(p.at(0).get<double>(), p.at(1).get<double>(),
                                  p.at(2).get<double>());
    }
    for (const auto& id : r.value("ids", json::array())) {
      e.input.ids.push_back(integer<std::uint32_t>(id, "ids"));
    }
    for (const auto& s : r.value("seeds", json::array())) {
      FoundSeed seed;
      seed.id = integer<std::uint32_t>(s.at("id"), "seeds.id");
      const json& p = s.at("lps");
      seed.lps_mm = {p.at(0).get<double>(), p.at(1).get<double>(), p.at(2).get<double>()};
      if (!seed.lps_mm.allFinite()) throw std::invalid_argument("seeds.lps: not finite");
      seed.length_mm = s.value("length_mm", 0.0);
      seed.width_mm = s.value("width_mm", 0.0);
      seed.kind = s.value("kind", "seed");
      if (seed.kind != "seed" && seed.kind != "tip") {
        throw std::invalid_argument("seeds.kind: '" + seed.kind + "' is neither seed nor tip");
      }
      for (const auto& q : s.value("path_lps", json::array())) {
        const Eigen::Vector3d point(q.at(0).get<double>(), q.at(1).get<double>(),
                                    q.at(2).get<double>());
        if (!point.allFinite()) throw std::invalid_argument("seeds.path_lps: not finite");
        seed.path_lps_mm.push_back(point);
      }
      e.input.seeds.push_back(seed);
    }
    e.input.error = r.value("error", "");
    e.input.job = integer(r, "job", std::uint64_t{0});
    e.input.summary = r.value("summary", "");
    e.input.loaded.source = r.value("source", "");
    e.input.loaded.description = r.value("description", "");
    e.input.plan_id = integer(r, "plan_id", std::uint64_t{0});
    e.input.digest = r.value("digest", "");
    e.input.robot_id = r.value("robot_id", "");
    e.input.session_uuid = r.value("session_uuid", "");
    if (r.contains("matrix")) {
      const json& m = r.at("matrix");
      if (!m.is_array() || m.size() != 16) throw std::invalid_argument("matrix: not 16 numbers");
      Eigen::Matrix4d matrix;
      for (int k = 0; k < 16; ++k)
        matrix(k / 4, k % 4) = m.at(k).get<double>();
      e.input.matrix = matrix;
    }
    if (r.contains("controller")) e.input.controller = readingFromJson(r.at("controller"));
    if (r.contains("reaim")) {
      const json& j = r.at("reaim");
      ReaimProposal p;
      p.job = e.input.job;
      p.target_id = integer<std::uint32_t>(j.at("target"), "reaim.target");
      p.source = j.at("source").get<std::string>();
      p.paused = jointsFrom(j.at("paused"), "reaim.paused");
      p.tip_lps_mm = vec3From(j.at("tip_lps"), "reaim.tip_lps");
      p.tip_robot_mm = vec3From(j.at("tip_robot"), "reaim.tip_robot");
      p.tip_offset_mm = j.at("tip_offset_mm").get<double>();
      p.path_rms_mm = j.at("path_rms_mm").get<double>();
      p.path_points = integer<std::size_t>(j.at("path_points"), "reaim.path_points");
      p.model = j.at("model").get<std::string>();
      p.message = j.at("message").get<std::string>();
      for (const auto& a : j.at("aims")) {
        ReaimedAim aim;
        aim.target_id = integer<std::uint32_t>(a.at("target"), "reaim.aims.target");
        aim.how = a.at("how").get<std::string>();
        if (aim.how != "path" && aim.how != "refit") {
          throw std::invalid_argument("reaim.aims.how: '" + aim.how +
                                      "' is neither path nor refit");
        }
        aim.before = jointsFrom(a.at("before"), "reaim.aims.before");
        aim.joints = jointsFrom(a.at("joints"), "reaim.aims.joints");
        aim.before_landing_robot_mm = vec3From(a.at("before_landing"), "reaim.aims.before_landing");
        aim.landing_robot_mm = vec3From(a.at("landing"), "reaim.aims.landing");
        p.aims.push_back(aim);
      }
      if (p.aims.empty() || p.aims.front().target_id != p.target_id) {
        throw std::invalid_argument("reaim.aims: the paused target's aim must come first");
      }
      e.input.reaim = std::move(p);
    }
    for (const auto& j : r.value("placements", json::array())) {
      placement::PlacedPose p;
      p.pose.origin_lps_mm = vec3From(j.at("origin_lps"), "placements.origin_lps");
      const json& m = j.at("rotation");
      if (!m.is_array() || m.size() != 9) throw std::invalid_argument("placements.rotation");
      for (int k = 0; k < 9; ++k)
        p.pose.rotation(k / 3, k % 3) = m.at(k).get<double>();
      if (!p.pose.rotation.allFinite() || !(p.pose.rotation.transpose() * p.pose.rotation)
                                               .isApprox(Eigen::Matrix3d::Identity(), 1e-6))
        throw std::invalid_argument("placements.rotation: not a rotation");
      p.coverage = coverageFrom(j.at("coverage"));
      p.skin = skinFrom(j.at("skin"));
      p.tilt_deg = j.at("tilt_deg").get<double>();
      p.shift_mm = j.at("shift_mm").get<double>();
      e.input.placements.push_back(std::move(p));
    }
    if (r.contains("mounted")) {
      const json& j = r.at("mounted");
      MountedPlacement m;
      m.deviation = {j.at("entry_mm").get<double>(), j.at("axis_deg").get<double>(),
                     j.at("depth_mm").get<double>()};
      m.coverage = coverageFrom(j.at("coverage"));
      m.skin = skinFrom(j.at("skin"));
      e.input.mounted = std::move(m);
    }
    if (r.contains("site")) {
      const json& j = r.at("site");
      anatomy::Site site;
      site.name = j.at("name").get<std::string>();
      for (const auto& entry : j.at("roles")) {
        anatomy::SiteRole role;
        role.name = entry.at("name").get<std::string>();
        role.aliases = entry.value("aliases", std::vector<std::string>{});
        const auto named = anatomy::roleNamed(entry.at("role").get<std::string>());
        if (!named) throw std::invalid_argument("site.roles.role: unknown");
        role.role = *named;
        role.margin_mm = entry.value("margin_mm", 0.0);
        if (entry.contains("dose_limits"))  // since issue 42
          for (const auto& [key, value] : doseLimitFields(role.dose_limits))
            if (entry.at("dose_limits").contains(key))
              *value = entry.at("dose_limits").at(key).get<double>();
        site.roles.push_back(std::move(role));
      }
      if (j.contains("placement")) {  // since issue 41's placement; before: the defaults
        const json& l = j.at("placement");
        auto& limits = site.placement;
        limits.approach = l.at("approach").get<std::string>();
        limits.insertion_lps = vec3From(l.at("insertion_lps"), "site.placement.insertion_lps");
        limits.max_tilt_deg = l.at("max_tilt_deg").get<double>();
        limits.max_shift_mm = l.at("max_shift_mm").get<double>();
        limits.min_skin_distance_mm = l.at("min_skin_distance_mm").get<double>();
        limits.skin_hu = l.at("skin_hu").get<double>();
        if (auto valid = limits.validate(); !valid.ok())
          throw std::invalid_argument("site." + valid.error().message);
      }
      if (j.contains("dosimetry")) {  // since issue 42
        const json& d = j.at("dosimetry");
        anatomy::SiteDosimetry dosimetry;
        dosimetry.seed_models_dir = d.at("seed_models_dir").get<std::string>();
        dosimetry.seed_models = d.at("seed_models").get<std::vector<std::string>>();
        dosimetry.seed_model = d.at("seed_model").get<std::string>();
        dosimetry.prescription_Gy = d.at("prescription_Gy").get<double>();
        dosimetry.strength_U = d.at("strength_U").get<double>();
        dosimetry.spacing_mm = d.at("spacing_mm").get<double>();
        site.dosimetry = std::move(dosimetry);
      }
      e.input.site = std::move(site);
    }
    if (r.contains("tissue")) {
      const json& t = r.at("tissue");
      config::TissueProfile profile;
      profile.name = t.at("name").get<std::string>();
      profile.source = t.value("source", "");
      profile.tissue = {t.at("lambda1").get<double>(), t.at("lambda2").get<double>()};
      profile.needle.curvature_per_mm = t.at("curvature_per_mm").get<double>();
      profile.needle.wheelbase_mm = t.at("wheelbase_mm").get<double>();
      e.input.tissue = std::move(profile);
    }
    if (r.contains("policy")) {
      const json& p = r.at("policy");
      ApprovalPolicy policy;
      policy.approvers = p.at("approvers").get<std::vector<std::string>>();
      policy.expiry_s = p.at("expiry_s").get<double>();
      policy.speed_steps_s = p.at("speed_steps_s").get<double>();
      policy.acceleration_steps_s2 = p.at("acceleration_steps_s2").get<double>();
      policy.limits.max_targets = integer(p, "max_targets", policy.limits.max_targets);
      policy.limits.max_total_rotation_rad =
          p.value("max_total_rotation_rad", policy.limits.max_total_rotation_rad);
      e.input.policy = std::move(policy);
    }
    return e;
  } catch (const json::exception& ex) {
    return bad(ex.what());
  } catch (const std::invalid_argument& ex) {
    return bad(ex.what());
  }
}

Expected<ReplayedStep> replayRecord(const Session& session, const std::string& line,
                                    const CtLoader& load_ct, const std::string& where) {
  auto entry = parseJournalRecord(line);
  if (!entry) return makeError(ErrorCode::kFormat, where + ": " + entry.error().message);
  Input& in = entry->input;
  // Journals from before issue 39 name no job on a CT load's outcome: there was one load at a
  // time, the one the session awaited.
  if ((in.kind == InputKind::kVolumeLoaded || in.kind == InputKind::kVolumeLoadFailed) &&
      in.job == 0) {
    in.job = session.ct_revision;
  }
  if (in.kind == InputKind::kVolumeLoaded) {
    auto ct = load_ct(in.loaded.source);
    if (!ct) {
      return makeError(ErrorCode::kIo,
                       where + ": cannot load the CT again (" + ct.error().message + ")");
    }
    in.loaded = std::move(ct).value();
  }
  if (in.kind == InputKind::kStructuresLoaded) {
    // Read again from the file, on the CT and with the site the session has: the same structures
    // unless the file changed since (the summary names each with its voxels).
    auto again = loadStructures(in.job, in.path, session.ct, session.site, *session.robot, {});
    if (again.kind != InputKind::kStructuresLoaded || again.summary != in.summary) {
      return makeError(ErrorCode::kIo,
                       fmt::format("{}: cannot load the structures again ({})", where,
                                   again.kind == InputKind::kStructuresLoaded
                                       ? "the file now holds " + again.summary
                                       : again.error));
    }
    in.structures = std::move(again.structures);
  }
  if (in.kind == InputKind::kDoseComputed &&
      jobKindSpec(JobKind::kDoseComputation).awaited(session) == in.job) {
    // Computed again on the session as it was asked (no files: they were written live): the
    // same dose unless a seed model's file changed since (the summary gives the metrics).
    auto again = computeDose(in.job, std::make_shared<const Session>(session), {});
    if (again.kind != InputKind::kDoseComputed || again.summary != in.summary) {
      return makeError(ErrorCode::kIo, fmt::format("{}: cannot compute the dose again ({})", where,
                                                   again.kind == InputKind::kDoseComputed
                                                       ? "it is now " + again.summary
                                                       : again.error));
    }
    in.dose = std::move(again.dose);
  }
  Step step = reduce(session, in);
  if (step.session.revision != entry->revision || toString(step.session.phase) != entry->phase) {
    // A refusal says why (the step's reply); a server's own input has no reply to show.
    std::string why;
    for (const auto& r : step.effects.replies) {
      if (!r.accepted)
        why = fmt::format(" ({} refused it: {}: {})", toString(in.kind), r.error_code, r.message);
    }
    return makeError(ErrorCode::kFormat,
                     fmt::format("{}: replaying it gives revision {} in {}, the record says "
                                 "revision {} in {}{}",
                                 where, step.session.revision, toString(step.session.phase),
                                 entry->revision, entry->phase, why));
  }
  return ReplayedStep{std::move(step), std::move(in)};
}

Expected<Session> replayJournal(Session session, const std::vector<std::string>& lines,
                                const CtLoader& load_ct, const std::string& journal_name) {
  for (std::size_t i = 0; i < lines.size(); ++i) {
    auto replayed =
        replayRecord(session, lines[i], load_ct, fmt::format("{} line {}", journal_name, i + 1));
    if (!replayed) return replayed.error();
    session = std::move(replayed->step.session);
  }
  return session;
}

}  // namespace ignav::workflow
