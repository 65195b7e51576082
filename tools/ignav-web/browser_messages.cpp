#include "browser_messages.hpp"

#include <openssl/evp.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace ignav::web {
namespace {

using nlohmann::json;

// Thrown inside the parser only; parseBrowserMessage turns it into a BadRequest.
struct BadField : std::runtime_error {
  using std::runtime_error::runtime_error;
};

const json* field(const json& msg, const char* name, bool required) {
  const auto it = msg.find(name);
  if (it == msg.end()) {
    if (required) throw BadField(std::string("'") + name + "' is missing");
    return nullptr;
  }
  return &*it;
}

std::uint64_t unsignedField(const json& msg, const char* name, bool required,
                            std::uint64_t fallback, std::uint64_t max) {
  const json* v = field(msg, name, required);
  if (!v) return fallback;
  if (!v->is_number_unsigned() && !(v->is_number_integer() && v->get<std::int64_t>() >= 0)) {
    throw BadField(std::string("'") + name + "' must be a non-negative integer, not " + v->dump());
  }
  const auto value = v->get<std::uint64_t>();
  if (value > max) {
    throw BadField(std::string("'") + name + "' is " + std::to_string(value) + ", above " +
                   std::to_string(max));
  }
  return value;
}

double numberField(const json& msg, const char* name, double fallback) {
  const json* v = field(msg, name, false);
  if (!v) return fallback;
  if (!v->is_number()) throw BadField(std::string("'") + name + "' must be a number");
  const double value = v->get<double>();
  if (!std::isfinite(value)) throw BadField(std::string("'") + name + "' must be finite");
  return value;
}

std::string stringField(const json& msg, const char* name, bool required,
                        const std::string& fallback = "") {
  const json* v = field(msg, name, required);
  if (!v) return fallback;
  if (!v->is_string()) throw BadField(std::string("'") + name + "' must be a string");
  return v->get<std::string>();
}

Eigen::Vector3d pointFrom(const json& p, const std::string& where) {
  if (!p.is_array() || p.size() != 3) throw BadField(where + " must be [x, y, z]");
  Eigen::Vector3d out;
  for (int i = 0; i < 3; ++i) {
    const json& c = p[static_cast<std::size_t>(i)];
    if (!c.is_number()) throw BadField(where + " must hold numbers");
    out[i] = c.get<double>();
    if (!std::isfinite(out[i])) throw BadField(where + " must be finite");
  }
  return out;
}

CommandRequest commandFrom(const json& msg) {
  CommandRequest out;
  out.kind = stringField(msg, "kind", true);
  if (!protocol::commandKindFromName(out.kind)) {
    throw BadField("'kind' \"" + out.kind + "\" is not a command (docs/PROTOCOL.md)");
  }
  out.args.path = stringField(msg, "path", false);
  if (const json* points = field(msg, "points", false)) {
    if (!points->is_array()) throw BadField("'points' must be an array");
    if (points->size() > kMaxPoints) {
      throw BadField("'points' holds " + std::to_string(points->size()) + " points, above " +
                     std::to_string(kMaxPoints));
    }
    for (std::size_t i = 0; i < points->size(); ++i)
      out.args.points.push_back(pointFrom((*points)[i], "points[" + std::to_string(i) + "]"));
  }
  if (const json* ids = field(msg, "ids", false)) {
    if (!ids->is_array()) throw BadField("'ids' must be an array");
    if (ids->size() > kMaxIds) {
      throw BadField("'ids' holds " + std::to_string(ids->size()) + " ids, above " +
                     std::to_string(kMaxIds));
    }
    for (std::size_t i = 0; i < ids->size(); ++i) {
      const json& id = (*ids)[i];
      if (!id.is_number_unsigned() || id.get<std::uint64_t>() > UINT32_MAX) {
        throw BadField("ids[" + std::to_string(i) + "] must be a target id (0 to 4294967295)");
      }
      out.args.ids.push_back(id.get<std::uint32_t>());
    }
  }
  // set_registration (and load_confirmation's optional one): 16 numbers, row by row,
  // p_robot = matrix * p_lps. The server judges what they mean; here only that they are numbers.
  if (const json* m = field(msg, "matrix", false)) {
    if (!m->is_array() || m->size() != 16) {
      throw BadField("'matrix' must be 16 numbers, row by row (p_robot = matrix * p_lps)");
    }
    Eigen::Matrix4d matrix;
    for (std::size_t k = 0; k < 16; ++k) {
      const json& v = (*m)[k];
      if (!v.is_number() || !std::isfinite(v.get<double>())) {
        throw BadField("matrix[" + std::to_string(k) + "] must be a finite number");
      }
      matrix(static_cast<Eigen::Index>(k / 4), static_cast<Eigen::Index>(k % 4)) = v.get<double>();
    }
    out.args.matrix = matrix;
  }
  return out;
}

SliceRequest sliceFrom(const json& msg) {
  SliceRequest out;
  out.args.view = stringField(msg, "view", true);
  out.args.centre_lps = pointFrom(*field(msg, "centre_lps", true), "'centre_lps'");
  out.args.size_px =
      static_cast<std::uint32_t>(unsignedField(msg, "size_px", false, 512, UINT32_MAX));
  out.args.pixel_mm = numberField(msg, "pixel_mm", 0.0);
  out.args.window = numberField(msg, "window", 0.0);
  out.args.level = numberField(msg, "level", 0.0);
  const std::string overlays = stringField(msg, "overlays", false, "region");
  if (overlays == "none") {
    out.args.overlays = false;
  } else if (overlays == "region") {
    out.args.overlays = out.args.region_only = true;
  } else if (overlays == "all") {
    out.args.overlays = true;
  } else {
    throw BadField("'overlays' \"" + overlays + "\" is not none, region or all");
  }
  return out;
}

}  // namespace

std::variant<BrowserRequest, BadRequest> parseBrowserMessage(std::string_view text) {
  if (text.size() > kMaxMessageBytes) {
    return BadRequest{std::nullopt, "the message has " + std::to_string(text.size()) +
                                        " bytes, above " + std::to_string(kMaxMessageBytes)};
  }
  const json msg = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (msg.is_discarded()) return BadRequest{std::nullopt, "the message is not JSON"};
  if (!msg.is_object()) return BadRequest{std::nullopt, "the message is not a JSON object"};
  BrowserRequest out;
  try {
    out.seq = unsignedField(msg, "seq", true, 0, std::numeric_limits<std::uint64_t>::max());
  } catch (const BadField& e) {
    return BadRequest{std::nullopt, e.what()};
  }
  try {
    const std::string op = stringField(msg, "op", true);
    if (op == "command") {
      out.body = commandFrom(msg);
    } else if (op == "approve") {
      ApproveRequest a;
      a.plan_id = unsignedField(msg, "plan_id", true, 0, std::numeric_limits<std::uint64_t>::max());
      a.digest = stringField(msg, "digest", true);
      out.body = a;
    } else if (op == "emergency_stop") {
      out.body = EmergencyStopRequest{};
    } else if (op == "slice") {
      out.body = sliceFrom(msg);
    } else if (op == "scene") {
      SceneRequest s;
      s.part = stringField(msg, "part", true);
      if (s.part != "volume" && s.part != "surfaces") {
        throw BadField("'part' \"" + s.part + "\" is not volume or surfaces");
      }
      s.first_slice =
          static_cast<std::uint32_t>(unsignedField(msg, "first_slice", false, 0, UINT32_MAX));
      s.max_voxels_per_axis = static_cast<std::uint32_t>(
          unsignedField(msg, "max_voxels_per_axis", false, 0, UINT32_MAX));
      out.body = s;
    } else {
      throw BadField("'op' \"" + op + "\" is not command, approve, emergency_stop, slice or scene");
    }
  } catch (const BadField& e) {
    return BadRequest{out.seq, e.what()};
  } catch (const json::exception& e) {  // a value of the right JSON type that does not convert
    return BadRequest{out.seq, e.what()};
  }
  return out;
}

json helloMessage(const std::string& client_id, const std::string& robot_id,
                  const std::string& subject, bool security, const std::string& version,
                  const std::vector<std::string>& permitted) {
  return {{"type", "hello"},       {"client_id", client_id}, {"robot_id", robot_id},
          {"subject", subject},    {"security", security},   {"version", version},
          {"permitted", permitted}};
}

json connectionMessage(bool server_matched) {
  return {{"type", "connection"}, {"server", server_matched}};
}

json stateMessage(const json& state, const std::vector<std::string>& changed) {
  json part = json::object();
  if (changed.empty()) {
    part = state;
  } else {
    for (const auto& topic : changed) {
      const std::string key = topic == "target" ? "targets" : topic;
      if (state.contains(key)) part[key] = state[key];
    }
  }
  return {{"type", "state"}, {"state", part}};
}

json replyMessage(std::uint64_t seq, const protocol::Reply& reply) {
  json message = reply;  // its JSON view, from the Reply's one list of fields
  message["type"] = "reply";
  message["seq"] = seq;
  return message;
}

json jobOutcomeMessage(const protocol::JobOutcome& outcome) {
  json message = outcome;  // its JSON view, from JobOutcome's one list of fields
  message["type"] = "job_outcome";
  return message;
}

json sliceMessage(std::uint64_t seq, const protocol::SliceResult& slice) {
  json m = json::array();
  for (int i = 0; i < 16; ++i)
    m.push_back(slice.pixel_to_lps(i / 4, i % 4));
  return {{"type", "slice"},      {"seq", seq},
          {"ok", slice.ok},       {"message", slice.message},
          {"width", slice.width}, {"height", slice.height},
          {"pixel_to_lps", m},    {"png_base64", slice.ok ? base64(slice.png) : std::string()}};
}

json sceneMessage(std::uint64_t seq, const protocol::SceneReply& scene) {
  static_assert(sizeof(float) == 4, "points travel as float32");
  json surfaces = json::array();
  for (const auto& s : scene.surfaces) {
    surfaces.push_back(
        {{"name", s.name},
         {"kind", s.kind},
         {"colour_rgb", s.colour_rgb},
         {"points_base64", base64(s.points_lps.data(), s.points_lps.size() * sizeof(float))},
         {"triangles_base64",
          base64(s.triangles.data(), s.triangles.size() * sizeof(std::uint32_t))}});
  }
  return {
      {"type", "scene"},
      {"seq", seq},
      {"ok", scene.ok},
      {"message", scene.message},
      {"part", scene.part},
      {"volume_id", scene.volume_id},
      {"dims", scene.dims},
      {"ijk_to_lps", scene.ijk_to_lps},
      {"value_scale", scene.value_scale},
      {"value_offset", scene.value_offset},
      {"first_slice", scene.first_slice},
      {"slice_count", scene.slice_count},
      {"voxels_base64", base64(scene.voxels.data(), scene.voxels.size() * sizeof(std::int16_t))},
      {"surfaces", surfaces}};
}

json errorMessage(std::optional<std::uint64_t> seq, const std::string& code,
                  const std::string& message) {
  return {
      {"type", "error"}, {"seq", seq ? json(*seq) : json()}, {"code", code}, {"message", message}};
}

std::string base64(const std::vector<std::uint8_t>& bytes) {
  return base64(bytes.data(), bytes.size());
}

std::string base64(const void* bytes, std::size_t size) {
  std::string out(4 * ((size + 2) / 3), '\0');
  if (size == 0) return out;
  // EVP_EncodeBlock writes a terminating NUL too: room for it, then trim.
  out.resize(out.size() + 1);
  const int n = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()),
                                static_cast<const unsigned char*>(bytes), static_cast<int>(size));
  out.resize(static_cast<std::size_t>(n));
  return out;
}

}  // namespace ignav::web
