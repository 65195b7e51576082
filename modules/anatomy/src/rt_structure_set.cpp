// RT Structure Sets: closed planar contours rasterised on the CT's voxels (dicom_structures.hpp).
#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmrt/drtstrct.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <optional>

#include "ignav/anatomy/dicom_structures.hpp"

namespace ignav::anatomy {
namespace {

// A contour's share of the slice's work: its points in the slice's (i, j), the slice's k.
struct SliceContour {
  int k = 0;
  std::vector<Eigen::Vector2d> points;
};

// Twice the signed area of triangle (o, a, b): > 0 when b lies left of o -> a.
double turn(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// Where segment ab crosses cd inside both (not where they merely touch or run along each other).
std::optional<Eigen::Vector2d> properCrossing(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                              const Eigen::Vector2d& c, const Eigen::Vector2d& d) {
  // Below this (voxels²) a point counts as on the line: DS strings carry ~1e-6 mm.
  constexpr double kOnLine = 1e-9;
  const double t1 = turn(c, d, a), t2 = turn(c, d, b), t3 = turn(a, b, c), t4 = turn(a, b, d);
  const bool ab_straddles = (t1 > kOnLine && t2 < -kOnLine) || (t1 < -kOnLine && t2 > kOnLine);
  const bool cd_straddles = (t3 > kOnLine && t4 < -kOnLine) || (t3 < -kOnLine && t4 > kOnLine);
  if (!ab_straddles || !cd_straddles) return std::nullopt;
  return a + (b - a) * (t1 / (t1 - t2));
}

// The first place a closed polygon crosses itself, if it does: edges swept by their lowest y so
// that only edges overlapping in y are compared (contours have hundreds of points).
std::optional<Eigen::Vector2d> selfCrossing(const std::vector<Eigen::Vector2d>& p) {
  const std::size_t n = p.size();
  auto lo = [&](std::size_t e) { return std::min(p[e].y(), p[(e + 1) % n].y()); };
  auto hi = [&](std::size_t e) { return std::max(p[e].y(), p[(e + 1) % n].y()); };
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return lo(a) < lo(b); });
  for (std::size_t x = 0; x < n; ++x) {
    const std::size_t e = order[x];
    for (std::size_t y = x + 1; y < n && lo(order[y]) <= hi(e); ++y) {
      const std::size_t f = order[y];
      if ((e + 1) % n == f || (f + 1) % n == e) continue;  // neighbours share a point
      if (auto at = properCrossing(p[e], p[(e + 1) % n], p[f], p[(f + 1) % n])) return at;
    }
  }
  return std::nullopt;
}

Error contourError(ErrorCode code, const std::string& what, std::size_t number,
                   const std::string& how, const char* reason) {
  return makeError(code, fmt::format("{}: contour {} {}", what, number, how), reason);
}

}  // namespace

Expected<Mask> rasteriseContours(const std::vector<PlanarContour>& contours,
                                 const volume::Geometry& ct, const std::string& what) {
  // A contour's points may reach half a voxel past the outermost centres (the voxels' own
  // extent, where planning systems put a body contour at the edge of the field), no further.
  constexpr double kEdge_voxels = 0.5 + 1e-6;
  constexpr double kOffSlice = 0.05;  // of the slice spacing
  std::vector<SliceContour> slices;
  for (std::size_t c = 0; c < contours.size(); ++c) {
    const std::size_t number = c + 1;
    SliceContour sc;
    double k_lo = INFINITY, k_hi = -INFINITY;
    for (const auto& lps : contours[c].points_lps_mm) {
      if (!lps.allFinite()) {
        return contourError(ErrorCode::kFormat, what, number, "has a coordinate that is not finite",
                            "format");
      }
      const Eigen::Vector3d ijk = ct.toIjk(lps);
      k_lo = std::min(k_lo, ijk.z());
      k_hi = std::max(k_hi, ijk.z());
      const Eigen::Vector2d ij = ijk.head<2>();
      // Repeated points (the closing point many systems repeat) add no edge.
      if (sc.points.empty() || (ij - sc.points.back()).norm() > 1e-9) sc.points.push_back(ij);
    }
    while (sc.points.size() > 1 && (sc.points.front() - sc.points.back()).norm() <= 1e-9)
      sc.points.pop_back();
    if (sc.points.size() < 3) {
      return contourError(ErrorCode::kFormat, what, number,
                          "has fewer than three distinct points: not a closed contour", "format");
    }
    const Eigen::Vector3d first =
        ct.toLps(Eigen::Vector3d(sc.points[0].x(), sc.points[0].y(), 0.5 * (k_lo + k_hi)));
    sc.k = static_cast<int>(std::lround(0.5 * (k_lo + k_hi)));
    if (k_hi - k_lo > 2 * kOffSlice || std::abs(0.5 * (k_lo + k_hi) - sc.k) > kOffSlice) {
      return contourError(
          ErrorCode::kInvalidArgument, what, number,
          fmt::format("(near {:.2f}, {:.2f}, {:.2f} mm LPS) does not lie in one of the CT's "
                      "slices: its points are {:.2f} to {:.2f} slices along the CT's k; the "
                      "structures were drawn on other slices",
                      first.x(), first.y(), first.z(), k_lo, k_hi),
          "other_ct");
    }
    for (const auto& ij : sc.points) {
      for (int a = 0; a < 2; ++a) {
        if (ij[a] < -kEdge_voxels ||
            ij[a] > ct.dims[static_cast<std::size_t>(a)] - 1 + kEdge_voxels || sc.k < 0 ||
            sc.k >= ct.dims[2]) {
          const Eigen::Vector3d at = ct.toLps(Eigen::Vector3d(ij.x(), ij.y(), sc.k));
          return contourError(
              ErrorCode::kInvalidArgument, what, number,
              fmt::format("reaches ({:.2f}, {:.2f}, {:.2f}) mm LPS, beyond the CT "
                          "({} x {} x {} voxels)",
                          at.x(), at.y(), at.z(), ct.dims[0], ct.dims[1], ct.dims[2]),
              "other_ct");
        }
      }
    }
    if (auto at = selfCrossing(sc.points)) {
      const Eigen::Vector3d lps = ct.toLps(Eigen::Vector3d(at->x(), at->y(), sc.k));
      return contourError(ErrorCode::kFormat, what, number,
                          fmt::format("crosses itself at ({:.2f}, {:.2f}, {:.2f}) mm LPS: inside "
                                      "and outside are undefined there",
                                      lps.x(), lps.y(), lps.z()),
                          "self_intersecting");
    }
    slices.push_back(std::move(sc));
  }
  if (slices.empty()) {
    return makeError(ErrorCode::kFormat, what + ": no closed contour", "empty_structure");
  }

  // The box of voxels the contours can enclose.
  int lo[3] = {ct.dims[0], ct.dims[1], ct.dims[2]}, hi[3] = {-1, -1, -1};
  for (const auto& sc : slices) {
    for (const auto& ij : sc.points) {
      for (int a = 0; a < 2; ++a) {
        lo[a] = std::min(lo[a], std::max(0, static_cast<int>(std::ceil(ij[a]))));
        hi[a] = std::max(hi[a], std::min(ct.dims[static_cast<std::size_t>(a)] - 1,
                                         static_cast<int>(std::floor(ij[a]))));
      }
    }
    lo[2] = std::min(lo[2], sc.k);
    hi[2] = std::max(hi[2], sc.k);
  }
  volume::Geometry box = ct;
  for (int a = 0; a < 3; ++a)
    box.dims[static_cast<std::size_t>(a)] = std::max(0, hi[a] - lo[a] + 1);
  box.origin_lps_mm = ct.toLps(Eigen::Vector3d(lo[0], lo[1], lo[2]));
  std::vector<std::uint8_t> inside(box.voxelCount(), 0);
  std::size_t set = 0;

  // Scan lines through the voxel centres of each row; all of a slice's edges together, so that
  // filling between alternate crossings is the even-odd rule over its contours. An edge counts
  // for a row when its ends lie on either side, one of them strictly above (half-open), so a
  // vertex on the row is counted once.
  std::map<int, std::vector<const SliceContour*>> by_slice;
  for (const auto& sc : slices)
    by_slice[sc.k].push_back(&sc);
  std::vector<double> xs;
  for (const auto& [k, on_slice] : by_slice) {
    for (int j = lo[1]; j <= hi[1]; ++j) {
      xs.clear();
      for (const SliceContour* sc : on_slice) {
        const auto& p = sc->points;
        for (std::size_t e = 0; e < p.size(); ++e) {
          const Eigen::Vector2d& a = p[e];
          const Eigen::Vector2d& b = p[(e + 1) % p.size()];
          if ((a.y() > j) == (b.y() > j)) continue;
          xs.push_back(a.x() + (j - a.y()) * (b.x() - a.x()) / (b.y() - a.y()));
        }
      }
      std::sort(xs.begin(), xs.end());
      for (std::size_t m = 0; m + 1 < xs.size(); m += 2) {
        const int from = std::max(lo[0], static_cast<int>(std::ceil(xs[m])));
        const int to = std::min(hi[0], static_cast<int>(std::ceil(xs[m + 1])) - 1);
        for (int i = from; i <= to; ++i) {
          auto& v = inside[gridIndex(box.dims, i - lo[0], j - lo[1], k - lo[2])];
          set += v == 0;
          v = 1;
        }
      }
    }
  }
  if (set == 0) {
    return makeError(
        ErrorCode::kFormat,
        what + ": its contours enclose no voxel centre of the CT (smaller than a voxel)",
        "empty_structure");
  }
  return cropMask(box, inside, what);
}

namespace {

std::string text(OFCondition (DRTStructureSetROISequence::Item::*get)(OFString&, signed long) const,
                 const DRTStructureSetROISequence::Item& item) {
  OFString value;
  return (item.*get)(value, 0).good() ? std::string(value.c_str()) : std::string();
}

}  // namespace

Expected<StructureSet> readRtStructureSet(const std::string& path, const CtFrame& ct) {
  DcmFileFormat file;
  if (OFCondition c = file.loadFile(path.c_str()); c.bad()) {
    return makeError(ErrorCode::kIo, path + ": cannot read as DICOM: " + c.text(), "format");
  }
  DRTStructureSetIOD rt;
  if (OFCondition c = rt.read(*file.getDataset()); c.bad()) {
    return makeError(ErrorCode::kFormat, path + ": not an RT Structure Set: " + c.text(), "format");
  }
  StructureSet set;
  set.source = path;
  auto refuse = [&](const std::string& how, const char* reason) {
    return makeError(ErrorCode::kFormat, path + ": " + how, reason);
  };

  // The ROIs' contours and colours, by ROI number.
  struct RoiDrawing {
    std::vector<PlanarContour> closed;
    std::size_t other = 0;  // points, open contours
    std::array<double, 3> colour_rgb{0.5, 0.5, 0.5};
  };
  std::map<Sint32, RoiDrawing> drawings;
  auto& contours_of = rt.getROIContourSequence();
  for (std::size_t r = 0; r < contours_of.getNumberOfItems(); ++r) {
    DRTROIContourSequence::Item* item = nullptr;
    if (contours_of.getItem(r, item).bad() || item == nullptr) continue;
    Sint32 number = 0;
    if (item->getReferencedROINumber(number).bad()) {
      return refuse(fmt::format("ROI Contour Sequence item {} names no ROI (3006,0084)", r + 1),
                    "format");
    }
    RoiDrawing& drawing = drawings[number];
    for (unsigned long c = 0; c < 3; ++c) {
      Sint32 v = 0;
      if (item->getROIDisplayColor(v, c).good()) {
        drawing.colour_rgb[c] = std::clamp(v, 0, 255) / 255.0;
      }
    }
    auto& contours = item->getContourSequence();
    for (std::size_t c = 0; c < contours.getNumberOfItems(); ++c) {
      DRTContourSequence::Item* contour = nullptr;
      if (contours.getItem(c, contour).bad() || contour == nullptr) continue;
      OFString type;
      contour->getContourGeometricType(type);
      if (type != "CLOSED_PLANAR") {
        ++drawing.other;
        continue;
      }
      OFVector<Float64> xyz;
      contour->getContourData(xyz);
      if (xyz.size() % 3 != 0) {
        return refuse(fmt::format("ROI {} contour {}: ContourData holds {} numbers, not x, y, z "
                                  "triples",
                                  number, c + 1, xyz.size()),
                      "format");
      }
      PlanarContour pc;
      for (std::size_t n = 0; n + 2 < xyz.size(); n += 3)
        pc.points_lps_mm.emplace_back(xyz[n], xyz[n + 1], xyz[n + 2]);
      drawing.closed.push_back(std::move(pc));
    }
  }

  // What planning systems call each ROI: their targets (PTV, CTV, GTV) are ignav's, their
  // avoidance structures are avoided (the site's margin applies when it names them).
  std::map<Sint32, Role> roles;
  auto& observations = rt.getRTROIObservationsSequence();
  for (std::size_t o = 0; o < observations.getNumberOfItems(); ++o) {
    DRTRTROIObservationsSequence::Item* item = nullptr;
    if (observations.getItem(o, item).bad() || item == nullptr) continue;
    Sint32 number = 0;
    OFString type;
    if (item->getReferencedROINumber(number).bad()) continue;
    item->getRTROIInterpretedType(type);
    if (type == "PTV" || type == "CTV" || type == "GTV") roles[number] = Role::kTarget;
    if (type == "AVOIDANCE") roles[number] = Role::kAvoid;
  }

  auto& rois = rt.getStructureSetROISequence();
  if (rois.getNumberOfItems() == 0)
    return refuse("the structure set lists no ROI", "empty_structure");
  bool frame_checked = false;
  for (std::size_t r = 0; r < rois.getNumberOfItems(); ++r) {
    DRTStructureSetROISequence::Item* roi = nullptr;
    if (rois.getItem(r, roi).bad() || roi == nullptr) continue;
    Sint32 number = 0;
    roi->getROINumber(number);
    const std::string name = text(&DRTStructureSetROISequence::Item::getROIName, *roi);
    if (name.empty()) {
      return refuse(fmt::format("ROI {} has no name (ROIName 3006,0026)", number), "names_missing");
    }
    if (set.find(name)) {
      return refuse(fmt::format("two ROIs are named '{}'", name), "format");
    }
    const auto found = drawings.find(number);
    if (found == drawings.end() || found->second.closed.empty()) {
      set.notes.push_back(fmt::format("'{}' {}: not a volume", name,
                                      found == drawings.end() || found->second.other == 0
                                          ? "has no contours"
                                          : "holds points or open contours only"));
      continue;
    }
    const std::string frame =
        text(&DRTStructureSetROISequence::Item::getReferencedFrameOfReferenceUID, *roi);
    if (!ct.frame_of_reference_uid.empty() && !frame.empty()) {
      if (frame != ct.frame_of_reference_uid) {
        return makeError(ErrorCode::kInvalidArgument,
                         fmt::format("{}: structure '{}' was not drawn on this CT ({}): its frame "
                                     "of reference is {}, the CT's {}",
                                     path, name, ct.name, frame, ct.frame_of_reference_uid),
                         "other_ct");
      }
      frame_checked = true;
    }
    auto mask = rasteriseContours(found->second.closed, ct.geometry,
                                  fmt::format("{}: structure '{}'", path, name));
    if (!mask) return mask.error();
    Structure s;
    s.name = name;
    s.colour_rgb = found->second.colour_rgb;
    if (const auto role = roles.find(number); role != roles.end()) s.role = role->second;
    s.mask = std::move(mask).value();
    set.structures.push_back(std::move(s));
  }
  if (set.structures.empty()) {
    return refuse("no ROI has closed planar contours: nothing to draw", "empty_structure");
  }
  if (!frame_checked) {
    set.notes.push_back(ct.frame_of_reference_uid.empty()
                            ? "frame of reference not checked: the CT's files carry none; its "
                              "slices and extent were"
                            : "frame of reference not checked: the structure set names none; the "
                              "CT's slices and extent were");
  }
  return set;
}

}  // namespace ignav::anatomy
