#include "ignav/volume/phantom.hpp"

#include <dcmtk/config/osconfig.h>  // must come first
//
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcuid.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

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

}  // namespace

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
  vol.modality = "CT";
  vol.description = "ignav phantom";
  vol.voxels.resize(g.voxelCount());
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
        if (spec.noise_sigma_hu > 0.0) hu += noise(rng);
        vol.voxels[vol.index(i, j, k)] =
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
                    frame_of_reference = uidFor(options.seed, 3);
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
