#include "ignav/volume/phantom.hpp"

#include <dcmtk/config/osconfig.h>  // must come first
//
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>
#include <string>

namespace ignav::volume {
namespace {

// A DICOM UID under the 2.25 root (UUID-derived, ISO/IEC 9834-8), made from a seed and a
// purpose so the same phantom always gets the same UIDs.
std::string uidFor(std::uint64_t seed, std::uint64_t purpose) {
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + purpose);
  const std::uint64_t a = rng(), b = rng() >> 4;  // ≤ 124 bits: fits the 64-char UID limit
  char buf[64];
  std::snprintf(buf, sizeof buf, "2.25.%llu%llu", static_cast<unsigned long long>(a),
                static_cast<unsigned long long>(b));
  return buf;
}

std::string decimals(const double* v, int n) {
  std::string out;
  for (int i = 0; i < n; ++i) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6f", v[i]);  // DS allows 16 characters
    std::string s = buf;
    s.erase(s.find_last_not_of('0') + 1);
    if (s.back() == '.') s.pop_back();
    out += (i ? "\\" : "") + s;
  }
  return out;
}

// One voxel's share of a seed: after the background and the fiducials are drawn, the voxel
// becomes (1 - fraction) * itself + fraction * seed_hu.
struct SeedVoxel {
  std::size_t index = 0;
  double fraction = 0.0;
};

// A voxel's response along one grid axis to a point at distance u (in voxels) from its centre:
// the scanner's Gaussian point spread (sigma in voxels) averaged over the voxel's width, i.e.
// Φ((u + ½)/σ) - Φ((u - ½)/σ); without a spread, 1 inside the voxel and 0 outside. The weights
// of all voxels sum to 1 for any point.
double voxelResponse(double u, double sigma_voxels) {
  if (sigma_voxels <= 0.0) return (u >= -0.5 && u < 0.5) ? 1.0 : 0.0;
  const double k = 1.0 / (std::sqrt(2.0) * sigma_voxels);
  return 0.5 * (std::erf((u + 0.5) * k) - std::erf((u - 0.5) * k));
}

// The voxels one seed covers and by how much: the cylinder filled with points on a grid
// symmetric about its centre (so their centroid is the centre exactly), each point spread by
// the point spread and averaged over the voxels (the scanner blurs before it samples, so the
// image of a seed thinner than a voxel is not aliased by more than the blur allows). In
// increasing voxel index.
std::vector<SeedVoxel> renderSeed(const Geometry& g, const PhantomSeed& seed, double psf_sigma_mm) {
  const Eigen::Vector3d axis = seed.axis_lps.normalized();
  const double h = 0.5 * seed.length_mm, r = 0.5 * seed.diameter_mm;
  // Two unit vectors across the axis.
  const Eigen::Vector3d any =
      std::abs(axis.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d across1 = axis.cross(any).normalized(), across2 = axis.cross(across1);
  // Point spacing: a 16th of the smaller of the diameter and the finest voxel side, coarser only
  // to keep a large "seed" under ~2 million points.
  double step = std::min(seed.diameter_mm, g.spacing_mm.minCoeff()) / 16.0;
  step = std::max(step, std::cbrt(M_PI * r * r * seed.length_mm / 2e6));
  const int n_along = std::max(1, static_cast<int>(std::ceil(seed.length_mm / step)));
  const int n_across = std::max(1, static_cast<int>(std::ceil(seed.diameter_mm / step)));
  const double step_along = seed.length_mm / n_along, step_across = seed.diameter_mm / n_across;
  // The local grid: the cylinder's IJK box grown by the spread's reach and a voxel.
  Eigen::Vector3d half_box;
  for (int a = 0; a < 3; ++a) {
    const double c = std::abs(axis[a]);
    half_box[a] = h * c + r * std::sqrt(std::max(0.0, 1.0 - c * c));
  }
  const Eigen::Vector3d sigma_voxels =
      Eigen::Vector3d::Constant(psf_sigma_mm).cwiseQuotient(g.spacing_mm);
  const Eigen::Vector3d reach = (4.0 * sigma_voxels).array() + 1.0;  // in voxels
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(std::numeric_limits<int>::max());
  Eigen::Vector3i hi = Eigen::Vector3i::Constant(std::numeric_limits<int>::min());
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d sign((corner & 1) ? 1 : -1, (corner & 2) ? 1 : -1, (corner & 4) ? 1 : -1);
    const Eigen::Vector3d ijk = g.toIjk(seed.centre_lps_mm + sign.cwiseProduct(half_box));
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], static_cast<int>(std::floor(ijk[a] - reach[a])));
      hi[a] = std::max(hi[a], static_cast<int>(std::ceil(ijk[a] + reach[a])));
    }
  }
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(lo[a], 0);
    hi[a] = std::min(hi[a], g.dims[a] - 1);
    if (lo[a] > hi[a]) return {};  // wholly outside the grid
  }
  const Eigen::Vector3i n = hi - lo + Eigen::Vector3i::Ones();
  auto at = [&](int i, int j, int k) {
    return static_cast<std::size_t>(i) +
           static_cast<std::size_t>(n[0]) *
               (static_cast<std::size_t>(j) +
                static_cast<std::size_t>(n[1]) * static_cast<std::size_t>(k));
  };
  std::vector<double> fraction(static_cast<std::size_t>(n.prod()), 0.0);
  // Each point stands for an equal share of the cylinder's exact volume (the points' square
  // cells only approximate the disc's area).
  std::size_t in_disc = 0;
  for (int u = 0; u < n_across; ++u)
    for (int v = 0; v < n_across; ++v) {
      const double x1 = -r + (u + 0.5) * step_across, x2 = -r + (v + 0.5) * step_across;
      in_disc += x1 * x1 + x2 * x2 <= r * r ? 1 : 0;
    }
  if (in_disc == 0) return {};
  const double point_share = M_PI * r * r * seed.length_mm /
                             (static_cast<double>(in_disc) * n_along) / g.spacing_mm.prod();
  std::array<std::vector<double>, 3> weight;
  std::array<int, 3> first{};
  for (int t = 0; t < n_along; ++t) {
    const double along = -h + (t + 0.5) * step_along;
    for (int u = 0; u < n_across; ++u) {
      const double x1 = -r + (u + 0.5) * step_across;
      for (int v = 0; v < n_across; ++v) {
        const double x2 = -r + (v + 0.5) * step_across;
        if (x1 * x1 + x2 * x2 > r * r) continue;
        const Eigen::Vector3d p =
            g.toIjk(seed.centre_lps_mm + along * axis + x1 * across1 + x2 * across2) -
            lo.cast<double>();
        bool inside = true;
        for (int a = 0; a < 3 && inside; ++a) {
          const int from = std::max(0, static_cast<int>(std::floor(p[a] - reach[a])));
          const int to = std::min(n[a] - 1, static_cast<int>(std::ceil(p[a] + reach[a])));
          first[static_cast<std::size_t>(a)] = from;
          auto& w = weight[static_cast<std::size_t>(a)];
          w.clear();
          for (int c = from; c <= to; ++c)
            w.push_back(voxelResponse(c - p[a], sigma_voxels[a]));
          inside = !w.empty();
        }
        if (!inside) continue;
        for (std::size_t c = 0; c < weight[2].size(); ++c) {
          const double wk = point_share * weight[2][c];
          if (wk == 0.0) continue;
          for (std::size_t b = 0; b < weight[1].size(); ++b) {
            const double wjk = wk * weight[1][b];
            if (wjk == 0.0) continue;
            double* row = &fraction[at(first[0], first[1] + static_cast<int>(b),
                                       first[2] + static_cast<int>(c))];
            for (std::size_t a = 0; a < weight[0].size(); ++a)
              row[a] += wjk * weight[0][a];
          }
        }
      }
    }
  }
  std::vector<SeedVoxel> out;
  const auto nx = static_cast<std::size_t>(g.dims[0]), ny = static_cast<std::size_t>(g.dims[1]);
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i) {
        const double f = std::min(1.0, fraction[at(i, j, k)]);
        if (f <= 1e-9) continue;
        const auto gi = static_cast<std::size_t>(lo[0] + i),
                   gj = static_cast<std::size_t>(lo[1] + j),
                   gk = static_cast<std::size_t>(lo[2] + k);
        out.push_back({gi + nx * (gj + ny * gk), f});
      }
  return out;
}

Status checkSeeds(const PhantomSpec& spec) {
  auto bad = [](const std::string& what) {
    return makeError(ErrorCode::kInvalidArgument, "phantom: " + what);
  };
  if (!std::isfinite(spec.seed_hu)) return bad("seed_hu must be finite");
  if (!(spec.seed_psf_sigma_mm >= 0.0) || !std::isfinite(spec.seed_psf_sigma_mm))
    return bad("seed_psf_sigma_mm must be finite and not negative");
  const std::size_t all = spec.seeds.size() + spec.needle_segments.size();
  for (std::size_t s = 0; s < all; ++s) {
    const bool is_seed = s < spec.seeds.size();
    const auto& seed = is_seed ? spec.seeds[s] : spec.needle_segments[s - spec.seeds.size()];
    const std::string name = is_seed
                                 ? "seed " + std::to_string(s + 1)
                                 : "needle segment " + std::to_string(s - spec.seeds.size() + 1);
    if (!seed.centre_lps_mm.allFinite() || !seed.axis_lps.allFinite())
      return bad(name + ": centre or axis not finite");
    if (!(seed.axis_lps.norm() > 1e-12)) return bad(name + ": axis has zero length");
    if (!(seed.length_mm > 0.0 && seed.diameter_mm > 0.0) || !std::isfinite(seed.length_mm) ||
        !std::isfinite(seed.diameter_mm))
      return bad(name + ": length_mm and diameter_mm must be finite and positive");
  }
  return Ok{};
}

}  // namespace

Expected<PhantomSpec> withSliceSpacing(PhantomSpec spec, double slice_mm) {
  constexpr double kMaxSlices = 4096;
  auto mm = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return std::string(buf);
  };
  if (!(slice_mm > 0.0) || !std::isfinite(slice_mm)) {
    return makeError(
        ErrorCode::kInvalidArgument,
        "phantom: the slice spacing must be a positive number of mm, not " + mm(slice_mm));
  }
  const double extent_mm = (spec.dims[2] - 1) * spec.spacing_mm.z();
  const double slices = std::max(1.0, std::round(extent_mm / slice_mm) + 1.0);
  if (!(slices <= kMaxSlices)) {
    return makeError(ErrorCode::kInvalidArgument,
                     "phantom: " + mm(slice_mm) + " mm slices across " + mm(extent_mm) +
                         " mm would take " + mm(slices) + " slices; at most " + mm(kMaxSlices));
  }
  spec.dims[2] = static_cast<int>(slices);
  spec.spacing_mm.z() = slice_mm;
  return spec;
}

void appendWire(PhantomSpec& spec, const std::vector<Eigen::Vector3d>& polyline_lps_mm,
                double diameter_mm) {
  for (std::size_t i = 1; i < polyline_lps_mm.size(); ++i) {
    const Eigen::Vector3d a = polyline_lps_mm[i - 1], b = polyline_lps_mm[i];
    const double length = (b - a).norm();
    if (!(length > 1e-9)) continue;
    spec.needle_segments.push_back({0.5 * (a + b), (b - a) / length, length, diameter_mm});
  }
}

Geometry phantomGeometry(const PhantomSpec& spec) {
  Geometry g;
  g.dims = spec.dims;
  g.spacing_mm = spec.spacing_mm;
  if (spec.oblique) {
    g.direction = Eigen::AngleAxisd(12.0 * M_PI / 180.0, Eigen::Vector3d(1, 1, 0).normalized())
                      .toRotationMatrix();
  }
  // Centre the grid on the LPS origin.
  const Eigen::Vector3d half_extent =
      0.5 * spec.spacing_mm.cwiseProduct(
                Eigen::Vector3d(spec.dims[0] - 1, spec.dims[1] - 1, spec.dims[2] - 1));
  g.origin_lps_mm = -(g.direction * half_extent);
  return g;
}

Expected<Volume> makePhantom(const PhantomSpec& spec) {
  Volume vol;
  vol.geometry = phantomGeometry(spec);
  const Geometry& g = vol.geometry;
  if (auto ok = g.validate("phantom"); !ok) return ok.error();
  for (const auto& f : spec.fiducials_lps_mm) {
    if (!f.allFinite())
      return makeError(ErrorCode::kInvalidArgument, "phantom: fiducial not finite");
  }
  if (!(spec.fiducial_radius_mm > 0.0)) {
    return makeError(ErrorCode::kInvalidArgument, "phantom: fiducial_radius_mm must be positive");
  }
  if (!(spec.noise_sigma_hu >= 0.0) || !std::isfinite(spec.noise_sigma_hu)) {
    return makeError(ErrorCode::kInvalidArgument,
                     "phantom: noise_sigma_hu must be finite and not negative");
  }
  if (auto ok = checkSeeds(spec); !ok) return ok.error();
  vol.modality = "CT";
  vol.description = "ignav phantom";
  vol.voxels.resize(g.voxelCount());
  // The seeds' voxels in increasing index (seed order within a voxel), walked by the scan below.
  std::vector<SeedVoxel> seed_voxels;
  for (const auto& seed : spec.seeds) {
    const auto one = renderSeed(g, seed, spec.seed_psf_sigma_mm);
    seed_voxels.insert(seed_voxels.end(), one.begin(), one.end());
  }
  // The needle's segments share the voxels at their joints: one body, so their shares add (the
  // blend below would count the overlap once too little).
  std::vector<SeedVoxel> needle_voxels;
  for (const auto& segment : spec.needle_segments) {
    const auto one = renderSeed(g, segment, spec.seed_psf_sigma_mm);
    needle_voxels.insert(needle_voxels.end(), one.begin(), one.end());
  }
  std::sort(needle_voxels.begin(), needle_voxels.end(),
            [](const SeedVoxel& a, const SeedVoxel& b) { return a.index < b.index; });
  for (std::size_t i = 0; i < needle_voxels.size();) {
    SeedVoxel merged{needle_voxels[i].index, 0.0};
    for (; i < needle_voxels.size() && needle_voxels[i].index == merged.index; ++i)
      merged.fraction += needle_voxels[i].fraction;
    merged.fraction = std::min(1.0, merged.fraction);
    seed_voxels.push_back(merged);
  }
  std::stable_sort(seed_voxels.begin(), seed_voxels.end(),
                   [](const SeedVoxel& a, const SeedVoxel& b) { return a.index < b.index; });
  std::size_t next_seed_voxel = 0;
  std::mt19937_64 rng(spec.seed);
  std::normal_distribution<double> noise(0.0, spec.noise_sigma_hu > 0 ? spec.noise_sigma_hu : 1.0);
  const double r = spec.fiducial_radius_mm;
  const double voxel_diag = 0.5 * spec.spacing_mm.norm();
  constexpr int kSuper = 4;  // partial volume: 4³ sub-samples per boundary voxel
  for (int k = 0; k < g.dims[2]; ++k) {
    for (int j = 0; j < g.dims[1]; ++j) {
      for (int i = 0; i < g.dims[0]; ++i) {
        const Eigen::Vector3d p = g.toLps(Eigen::Vector3d(i, j, k));
        const bool in_box = (p.cwiseAbs() - spec.box_half_extent_mm).maxCoeff() <= 0.0;
        double hu = in_box ? spec.box_hu : spec.air_hu;
        for (const auto& c : spec.fiducials_lps_mm) {
          const double d = (p - c).norm();
          if (d > r + voxel_diag) continue;
          double inside = 1.0;
          if (d > r - voxel_diag) {
            int hits = 0;
            for (int a = 0; a < kSuper; ++a)
              for (int b = 0; b < kSuper; ++b)
                for (int e = 0; e < kSuper; ++e) {
                  const Eigen::Vector3d off((a + 0.5) / kSuper - 0.5, (b + 0.5) / kSuper - 0.5,
                                            (e + 0.5) / kSuper - 0.5);
                  const Eigen::Vector3d q = g.toLps(Eigen::Vector3d(i, j, k) + off);
                  hits += (q - c).norm() <= r ? 1 : 0;
                }
            inside = hits / double(kSuper * kSuper * kSuper);
          }
          hu = (1.0 - inside) * hu + inside * spec.fiducial_hu;
        }
        const std::size_t index = vol.index(i, j, k);
        for (; next_seed_voxel < seed_voxels.size() && seed_voxels[next_seed_voxel].index == index;
             ++next_seed_voxel) {
          const double f = seed_voxels[next_seed_voxel].fraction;
          hu = (1.0 - f) * hu + f * spec.seed_hu;
        }
        if (spec.noise_sigma_hu > 0.0) hu += noise(rng);
        vol.voxels[index] =
            static_cast<std::int16_t>(std::clamp(std::lround(hu), -1024L, 32767L - 1024L));
      }
    }
  }
  return vol;
}

Expected<std::vector<std::string>> writeDicomSeries(const Volume& vol, const std::string& dir,
                                                    const DicomWriteOptions& options) {
  const Geometry& g = vol.geometry;
  if (auto ok = g.validate("volume to write"); !ok) return ok.error();
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return makeError(ErrorCode::kIo, dir + ": cannot create directory: " + ec.message());
  const std::string study = uidFor(options.seed, 1), series = uidFor(options.seed, 2),
                    frame_of_reference = vol.frame_of_reference_uid.empty()
                                             ? uidFor(options.seed, 3)
                                             : vol.frame_of_reference_uid;
  const Eigen::Vector3d row = g.direction.col(0), col = g.direction.col(1);
  const double iop[6] = {row.x(), row.y(), row.z(), col.x(), col.y(), col.z()};
  const double spacing[2] = {g.spacing_mm.y(), g.spacing_mm.x()};  // [row spacing, col spacing]
  const std::size_t plane = static_cast<std::size_t>(g.dims[0]) * g.dims[1];
  std::vector<Uint16> pixels(plane);
  std::vector<std::string> written;
  for (int k = 0; k < g.dims[2]; ++k) {
    DcmFileFormat ff;
    DcmDataset& ds = *ff.getDataset();
    const Eigen::Vector3d ipp = g.toLps(Eigen::Vector3d(0, 0, k));
    const double ipp3[3] = {ipp.x(), ipp.y(), ipp.z()};
    const int instance = options.reverse_instance_numbers ? g.dims[2] - k : k + 1;
    char name[32];
    std::snprintf(name, sizeof name, "slice_%04d.dcm", k);
    const std::string path = (std::filesystem::path(dir) / name).string();
    OFCondition c = EC_Normal;
    auto put = [&](const DcmTagKey& tag, const std::string& v) {
      if (c.good()) c = ds.putAndInsertString(tag, v.c_str());
    };
    put(DCM_SOPClassUID, UID_CTImageStorage);
    put(DCM_SOPInstanceUID, uidFor(options.seed, 1000 + static_cast<std::uint64_t>(k)));
    put(DCM_StudyInstanceUID, study);
    put(DCM_SeriesInstanceUID, series);
    put(DCM_FrameOfReferenceUID, frame_of_reference);
    put(DCM_Modality, "CT");
    put(DCM_PatientName, options.patient_name);
    put(DCM_PatientID, "IGNAV-PHANTOM");
    put(DCM_SeriesDescription, options.series_description);
    put(DCM_SeriesNumber, "1");
    put(DCM_InstanceNumber, std::to_string(instance));
    put(DCM_ImageType, "ORIGINAL\\PRIMARY\\AXIAL");
    put(DCM_ImagePositionPatient, decimals(ipp3, 3));
    put(DCM_ImageOrientationPatient, decimals(iop, 6));
    put(DCM_PixelSpacing, decimals(spacing, 2));
    put(DCM_SliceThickness, decimals(&g.spacing_mm.z(), 1));
    put(DCM_PhotometricInterpretation, "MONOCHROME2");
    put(DCM_RescaleIntercept, "-1024");
    put(DCM_RescaleSlope, "1");
    put(DCM_RescaleType, "HU");
    if (c.good()) c = ds.putAndInsertUint16(DCM_SamplesPerPixel, 1);
    if (c.good()) c = ds.putAndInsertUint16(DCM_Rows, static_cast<Uint16>(g.dims[1]));
    if (c.good()) c = ds.putAndInsertUint16(DCM_Columns, static_cast<Uint16>(g.dims[0]));
    if (c.good()) c = ds.putAndInsertUint16(DCM_BitsAllocated, 16);
    if (c.good()) c = ds.putAndInsertUint16(DCM_BitsStored, 16);
    if (c.good()) c = ds.putAndInsertUint16(DCM_HighBit, 15);
    if (c.good()) c = ds.putAndInsertUint16(DCM_PixelRepresentation, 0);
    for (std::size_t p = 0; p < plane; ++p) {
      const double hu =
          vol.voxels[plane * static_cast<std::size_t>(k) + p] * vol.value_scale + vol.value_offset;
      pixels[p] = static_cast<Uint16>(std::clamp(std::lround(hu + 1024.0), 0L, 65535L));
    }
    if (c.good()) {
      c = ds.putAndInsertUint16Array(DCM_PixelData, pixels.data(),
                                     static_cast<unsigned long>(plane));
    }
    if (c.good()) c = ff.saveFile(path.c_str(), EXS_LittleEndianExplicit);
    if (c.bad()) return makeError(ErrorCode::kIo, path + ": cannot write DICOM: " + c.text());
    written.push_back(path);
  }
  return written;
}

}  // namespace ignav::volume
