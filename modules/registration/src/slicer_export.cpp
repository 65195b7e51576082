#include "ignav/registration/slicer_export.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

namespace ignav::registration {
namespace {

// Slicer identifies the format by this id; it need not resolve.
constexpr const char* kMarkupsSchema =
    "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/"
    "Schema/markups-schema-v1.0.3.json#";

// Beside it first, then renamed over it: a reader (Slicer, a test) never sees half a file, as the
// session's exports are rewritten while the session runs.
Status writeText(const std::string& text, const std::string& path) {
  const std::string aside = path + ".partial";
  {
    std::ofstream out(aside, std::ios::binary | std::ios::trunc);
    if (!out) return makeError(ErrorCode::kIo, path + ": cannot open for writing");
    out << text;
    out.flush();
    if (!out) return makeError(ErrorCode::kIo, path + ": write failed");
  }
  std::error_code ec;
  std::filesystem::rename(aside, path, ec);
  if (ec) return makeError(ErrorCode::kIo, path + ": cannot replace: " + ec.message());
  return Ok{};
}

}  // namespace

std::string itkTransformText(const Registration& registration) {
  // + 0.0 writes a negative zero (from a rotation's exact terms) as 0, not -0.
  const Eigen::Matrix4d m = registration.imageToRobot().array() + 0.0;
  std::string text = "#Insight Transform File V1.0\n#Transform 0\n";
  text += "Transform: AffineTransform_double_3_3\nParameters:";
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c)
      text += fmt::format(" {:.17g}", m(r, c));
  }
  for (int r = 0; r < 3; ++r)
    text += fmt::format(" {:.17g}", m(r, 3));
  text += "\nFixedParameters: 0 0 0\n";
  return text;
}

Status writeItkTransform(const Registration& registration, const std::string& path) {
  if (!registration.imageToRobot().allFinite()) {
    return makeError(ErrorCode::kInvalidArgument, path + ": the transform is not finite");
  }
  return writeText(itkTransformText(registration), path);
}

std::string markupsJsonText(const std::string& name, const std::vector<MarkupPoint>& points) {
  using nlohmann::json;
  json control_points = json::array();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    control_points.push_back(
        {{"id", std::to_string(i + 1)},
         {"label", p.label},
         {"description", p.description},
         {"position", {p.position_lps_mm.x(), p.position_lps_mm.y(), p.position_lps_mm.z()}},
         {"locked", p.locked},
         {"visibility", true},
         {"positionStatus", "defined"}});
  }
  const json doc = {{"@schema", kMarkupsSchema},
                    {"markups",
                     {{{"type", "Fiducial"},
                       {"name", name},
                       {"coordinateSystem", "LPS"},
                       {"coordinateUnits", "mm"},
                       {"locked", true},
                       {"controlPoints", control_points}}}}};
  return doc.dump(2) + "\n";
}

Status writeMarkupsJson(const std::string& name, const std::vector<MarkupPoint>& points,
                        const std::string& path) {
  for (const auto& p : points) {
    if (!p.position_lps_mm.allFinite()) {
      return makeError(ErrorCode::kInvalidArgument,
                       path + ": point '" + p.label + "' has a non-finite coordinate");
    }
  }
  return writeText(markupsJsonText(name, points), path);
}

}  // namespace ignav::registration
