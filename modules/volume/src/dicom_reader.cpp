// DICOM series reader on DCMTK. Two passes: headers of every file (pixel data is left on disk by
// DCMTK's lazy loading), then the chosen series' pixels, decoded straight into the volume.
#include <dcmtk/config/osconfig.h>  // must come first
//
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfcache.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcmetinf.h>
#include <dcmtk/dcmdata/dcpixel.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmjpeg/djdecode.h>
#include <dcmtk/dcmjpls/djdecode.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <climits>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

#include "ignav/volume/dicom.hpp"

namespace ignav::volume {
namespace {

namespace fs = std::filesystem;

void registerDecodersOnce() {
  // DCMTK keeps its codec registry process-wide; registering twice is harmless but wasteful.
  static std::once_flag once;
  std::call_once(once, [] {
    DJDecoderRegistration::registerCodecs();
    DJLSDecoderRegistration::registerCodecs();
    DcmRLEDecoderRegistration::registerCodecs();
  });
}

// What one file says about its image(s).
struct FileHeader {
  std::string path;
  std::string series_uid, modality, description, frame_of_reference_uid;
  std::string study_uid, patient_name, patient_id;
  int rows = 0, cols = 0, frames = 1;
  Eigen::Vector3d row_dir, col_dir;         // IOP
  double row_spacing = 0, col_spacing = 0;  // PixelSpacing [row spacing, column spacing]
  double slice_thickness = 0;
  int bits_allocated = 0, bits_stored = 0, pixel_representation = 0, samples = 1;
  std::string photometric;
  double slope = 1.0, intercept = 0.0;
  std::vector<Eigen::Vector3d> frame_positions;  // IPP of each frame
};

// Stored pixels of one frame -> int16 voxels: mask the bits above BitsStored (they may hold
// overlays), sign-extend signed data, add the integer rescale shift. Branch-free so that it
// vectorises; returns the range of the results, which the caller checks once per frame.
template <typename Raw>
__attribute__((always_inline)) inline std::pair<std::int32_t, std::int32_t> convertFrame(
    const Raw* in, std::int16_t* out, std::size_t n, std::uint32_t mask, std::int32_t sign_bit,
    std::int32_t add) {
  std::int32_t lo = INT32_MAX, hi = INT32_MIN;
  for (std::size_t p = 0; p < n; ++p) {
    const auto masked = static_cast<std::int32_t>(in[p] & mask);
    const std::int32_t value = (masked ^ sign_bit) - sign_bit + add;
    lo = std::min(lo, value);
    hi = std::max(hi, value);
    out[p] = static_cast<std::int16_t>(value);
  }
  return {lo, hi};
}

// ThreadSanitizer instruments the resolver that target_clones makes, and the dynamic linker runs
// it before TSan's runtime is up: every TSan binary died before main (docs/RELIABILITY.md).
#if defined(__SANITIZE_THREAD__)
#define IGNAV_THREAD_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define IGNAV_THREAD_SANITIZER 1
#endif
#endif
#ifdef IGNAV_THREAD_SANITIZER
#define IGNAV_AVX2_CLONES
#else
#define IGNAV_AVX2_CLONES __attribute__((target_clones("avx2", "default")))
#endif

// The conversion is the reader's hottest loop; AVX2 (when the CPU has it) halves its cost over
// the SSE2 baseline, chosen once at load time by the dynamic linker.
IGNAV_AVX2_CLONES std::pair<std::int32_t, std::int32_t> convert16(const std::uint16_t* in,
                                                                  std::int16_t* out, std::size_t n,
                                                                  std::uint32_t mask,
                                                                  std::int32_t sign_bit,
                                                                  std::int32_t add) {
  return convertFrame(in, out, n, mask, sign_bit, add);
}

struct Frame {
  std::size_t file;
  int frame;
  double along_normal_mm;
};

std::string str(DcmItem& item, const DcmTagKey& tag) {
  OFString v;
  if (item.findAndGetOFStringArray(tag, v).good()) return std::string(v.c_str());
  return {};
}

bool floats(DcmItem& item, const DcmTagKey& tag, double* out, unsigned long n) {
  for (unsigned long i = 0; i < n; ++i) {
    Float64 v = 0;
    if (item.findAndGetFloat64(tag, v, i).bad() || !std::isfinite(v)) return false;
    out[i] = v;
  }
  return true;
}

// An item of a sequence inside `parent`, or nullptr.
DcmItem* sequenceItem(DcmItem& parent, const DcmTagKey& seq, long index = 0) {
  DcmItem* item = nullptr;
  if (parent.findAndGetSequenceItem(seq, item, index).good()) return item;
  return nullptr;
}

std::string describeNum(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// Reads geometry and pixel format from one file. Returns an error for a DICOM image we cannot
// use; `skip_reason` is set instead for files that are not images (they are noted, not errors).
Expected<FileHeader> readHeader(const std::string& path, DcmFileFormat& ff, std::string& skip) {
  DcmDataset& ds = *ff.getDataset();
  DcmMetaInfo& meta = *ff.getMetaInfo();
  const std::string sop_class = str(meta, DCM_MediaStorageSOPClassUID);
  if (sop_class == UID_MediaStorageDirectoryStorage) {
    skip = "DICOMDIR (a directory index, not an image)";
    return makeError(ErrorCode::kFormat, skip);
  }
  FileHeader h;
  h.path = path;
  h.modality = str(ds, DCM_Modality);
  if (!ds.tagExists(DCM_PixelData)) {
    skip = "no pixel data (" + (h.modality.empty() ? std::string("non-image") : h.modality) + ")";
    return makeError(ErrorCode::kFormat, skip);
  }
  auto bad = [&](const std::string& what) {
    return makeError(ErrorCode::kFormat, path + ": " + what);
  };
  h.series_uid = str(ds, DCM_SeriesInstanceUID);
  if (h.series_uid.empty()) return bad("missing SeriesInstanceUID (0020,000E)");
  h.description = str(ds, DCM_SeriesDescription);
  h.frame_of_reference_uid = str(ds, DCM_FrameOfReferenceUID);
  h.study_uid = str(ds, DCM_StudyInstanceUID);
  h.patient_name = str(ds, DCM_PatientName);
  h.patient_id = str(ds, DCM_PatientID);
  Uint16 u16 = 0;
  auto needU16 = [&](const DcmTagKey& tag, int& out) {
    if (ds.findAndGetUint16(tag, u16).bad()) return false;
    out = u16;
    return true;
  };
  if (!needU16(DCM_Rows, h.rows)) return bad("missing Rows (0028,0010)");
  if (!needU16(DCM_Columns, h.cols)) return bad("missing Columns (0028,0011)");
  if (!needU16(DCM_BitsAllocated, h.bits_allocated)) {
    return bad("missing BitsAllocated (0028,0100)");
  }
  if (!needU16(DCM_BitsStored, h.bits_stored)) h.bits_stored = h.bits_allocated;
  if (!needU16(DCM_PixelRepresentation, h.pixel_representation)) {
    return bad("missing PixelRepresentation (0028,0103)");
  }
  if (!needU16(DCM_SamplesPerPixel, h.samples)) h.samples = 1;
  h.photometric = str(ds, DCM_PhotometricInterpretation);
  if (h.rows == 0 || h.cols == 0) return bad("Rows or Columns is 0");

  Sint32 frames = 1;
  if (ds.findAndGetSint32(DCM_NumberOfFrames, frames).bad()) frames = 1;
  if (frames < 1) return bad("NumberOfFrames is " + std::to_string(frames));
  h.frames = frames;
  // Native pixel data must hold what Rows x Columns x NumberOfFrames declare, so that a lying
  // header cannot make the reader allocate gigabytes for a small file.
  DcmElement* pixels = nullptr;
  if (!DcmXfer(ds.getOriginalXfer()).isEncapsulated() &&
      ds.findAndGetElement(DCM_PixelData, pixels).good()) {
    const std::uint64_t declared = static_cast<std::uint64_t>(h.rows) * h.cols * h.frames *
                                   static_cast<std::uint64_t>(h.bits_allocated) / 8;
    if (pixels->getLength() < declared) {
      return bad("declares " + std::to_string(h.cols) + " x " + std::to_string(h.rows) + " x " +
                 std::to_string(h.frames) + " pixels (" + std::to_string(declared) +
                 " bytes) but its PixelData holds " + std::to_string(pixels->getLength()) +
                 " bytes");
    }
  }

  // Geometry: classic tags, or the functional groups of enhanced multi-frame objects.
  DcmItem* shared = sequenceItem(ds, DCM_SharedFunctionalGroupsSequence);
  DcmItem* first_frame = sequenceItem(ds, DCM_PerFrameFunctionalGroupsSequence, 0);
  auto fromGroups = [&](const DcmTagKey& seq, const DcmTagKey& tag, double* out, unsigned long n) {
    for (DcmItem* group : {first_frame, shared}) {
      if (group == nullptr) continue;
      DcmItem* item = sequenceItem(*group, seq);
      if (item != nullptr && floats(*item, tag, out, n)) return true;
    }
    return false;
  };
  double iop[6];
  if (!floats(ds, DCM_ImageOrientationPatient, iop, 6) &&
      !fromGroups(DCM_PlaneOrientationSequence, DCM_ImageOrientationPatient, iop, 6)) {
    return bad("missing or invalid ImageOrientationPatient (0020,0037)");
  }
  h.row_dir = {iop[0], iop[1], iop[2]};
  h.col_dir = {iop[3], iop[4], iop[5]};
  if (std::abs(h.row_dir.norm() - 1.0) > 1e-3 || std::abs(h.col_dir.norm() - 1.0) > 1e-3 ||
      std::abs(h.row_dir.dot(h.col_dir)) > 1e-3) {
    return bad("ImageOrientationPatient is not two orthonormal vectors");
  }
  h.row_dir.normalize();
  h.col_dir.normalize();
  double ps[2];
  if (!floats(ds, DCM_PixelSpacing, ps, 2) &&
      !fromGroups(DCM_PixelMeasuresSequence, DCM_PixelSpacing, ps, 2)) {
    return bad("missing or invalid PixelSpacing (0028,0030)");
  }
  if (!(ps[0] > 0.0) || !(ps[1] > 0.0)) {
    return bad("PixelSpacing " + describeNum(ps[0]) + "\\" + describeNum(ps[1]) +
               " mm must be positive");
  }
  h.row_spacing = ps[0];
  h.col_spacing = ps[1];
  double thickness = 0.0;
  if (floats(ds, DCM_SliceThickness, &thickness, 1) ||
      fromGroups(DCM_PixelMeasuresSequence, DCM_SliceThickness, &thickness, 1)) {
    h.slice_thickness = thickness;
  }

  // Rescale: a missing tag means identity (findAndGet writes 0 on failure: never trust it).
  double v = 0.0;
  if (floats(ds, DCM_RescaleSlope, &v, 1) ||
      fromGroups(DCM_PixelValueTransformationSequence, DCM_RescaleSlope, &v, 1)) {
    h.slope = v;
  }
  if (floats(ds, DCM_RescaleIntercept, &v, 1) ||
      fromGroups(DCM_PixelValueTransformationSequence, DCM_RescaleIntercept, &v, 1)) {
    h.intercept = v;
  }
  if (h.slope == 0.0) return bad("RescaleSlope is 0");

  // Frame positions.
  const Eigen::Vector3d normal = h.row_dir.cross(h.col_dir);
  double ipp[3];
  if (h.frames == 1 && floats(ds, DCM_ImagePositionPatient, ipp, 3)) {
    h.frame_positions.emplace_back(ipp[0], ipp[1], ipp[2]);
  } else if (first_frame != nullptr) {
    for (int f = 0; f < h.frames; ++f) {
      DcmItem* group = sequenceItem(ds, DCM_PerFrameFunctionalGroupsSequence, f);
      DcmItem* pos = group ? sequenceItem(*group, DCM_PlanePositionSequence) : nullptr;
      if (pos == nullptr || !floats(*pos, DCM_ImagePositionPatient, ipp, 3)) {
        return bad("frame " + std::to_string(f + 1) + " has no PlanePositionSequence position");
      }
      h.frame_positions.emplace_back(ipp[0], ipp[1], ipp[2]);
    }
  } else if (floats(ds, DCM_ImagePositionPatient, ipp, 3)) {
    // Legacy multi-frame (e.g. RT dose): frames offset along the normal by GridFrameOffsetVector.
    std::vector<double> offsets(static_cast<std::size_t>(h.frames));
    if (!floats(ds, DCM_GridFrameOffsetVector, offsets.data(), offsets.size())) {
      return bad(std::to_string(h.frames) +
                 " frames but neither per-frame positions nor GridFrameOffsetVector (3004,000C)");
    }
    const Eigen::Vector3d origin(ipp[0], ipp[1], ipp[2]);
    for (double o : offsets)
      h.frame_positions.push_back(origin + o * normal);
  } else {
    return bad("missing ImagePositionPatient (0020,0032)");
  }
  return h;
}

Status checkPixelFormat(const FileHeader& h) {
  auto unsupported = [&](const std::string& what) {
    return makeError(ErrorCode::kUnsupported, h.path + ": " + what);
  };
  if (h.samples != 1) {
    return unsupported("SamplesPerPixel " + std::to_string(h.samples) +
                       " (colour images are not CT volumes)");
  }
  if (h.photometric != "MONOCHROME2" && h.photometric != "MONOCHROME1") {
    return unsupported("PhotometricInterpretation '" + h.photometric + "'; expected MONOCHROME2");
  }
  if (h.bits_allocated != 8 && h.bits_allocated != 16) {
    return unsupported("BitsAllocated " + std::to_string(h.bits_allocated) +
                       "; only 8 and 16 bit greyscale are supported");
  }
  if (h.bits_stored < 1 || h.bits_stored > h.bits_allocated) {
    return makeError(ErrorCode::kFormat, h.path + ": BitsStored " + std::to_string(h.bits_stored) +
                                             " does not fit BitsAllocated " +
                                             std::to_string(h.bits_allocated));
  }
  return Ok{};
}

// The series' pixel layout must be one grid: same size, orientation and spacing in every file.
Status checkConsistent(const FileHeader& a, const FileHeader& b) {
  auto differ = [&](const std::string& what) {
    return makeError(ErrorCode::kFormat,
                     "inconsistent series: " + b.path + " differs from " + a.path + " in " + what);
  };
  if (a.rows != b.rows || a.cols != b.cols) {
    return differ("size (" + std::to_string(b.cols) + "x" + std::to_string(b.rows) + " vs " +
                  std::to_string(a.cols) + "x" + std::to_string(a.rows) + ")");
  }
  if ((a.row_dir - b.row_dir).norm() > 1e-4 || (a.col_dir - b.col_dir).norm() > 1e-4) {
    return differ("ImageOrientationPatient");
  }
  if (std::abs(a.row_spacing - b.row_spacing) > 1e-4 ||
      std::abs(a.col_spacing - b.col_spacing) > 1e-4) {
    return differ("PixelSpacing");
  }
  if (a.bits_allocated != b.bits_allocated || a.pixel_representation != b.pixel_representation ||
      a.bits_stored != b.bits_stored) {
    return differ("pixel format (BitsAllocated/BitsStored/PixelRepresentation)");
  }
  if (a.slope != b.slope || a.intercept != b.intercept) {
    return makeError(ErrorCode::kUnsupported,
                     "per-slice rescale: " + b.path + " has RescaleSlope/Intercept " +
                         describeNum(b.slope) + "/" + describeNum(b.intercept) + " but " + a.path +
                         " has " + describeNum(a.slope) + "/" + describeNum(a.intercept));
  }
  return Ok{};
}

std::vector<std::string> collectFiles(const std::vector<std::string>& paths,
                                      std::vector<std::string>& notes, Status& status) {
  std::vector<std::string> files;
  for (const std::string& p : paths) {
    std::error_code ec;
    if (fs::is_directory(p, ec)) {
      for (auto it = fs::recursive_directory_iterator(
               p, fs::directory_options::skip_permission_denied, ec);
           !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
        if (it->is_regular_file(ec)) files.push_back(it->path().string());
      }
      if (ec) notes.push_back(p + ": directory walk stopped: " + ec.message());
    } else if (fs::is_regular_file(p, ec)) {
      files.push_back(p);
    } else {
      status = makeError(ErrorCode::kIo, p + ": no such file or directory");
      return {};
    }
  }
  std::sort(files.begin(), files.end());  // deterministic notes; slice order comes from geometry
  return files;
}

// How stored pixels become voxels, the same for every file of a series.
struct PixelLayout {
  std::size_t plane = 0, frame_bytes = 0;  // voxels and stored bytes per frame
  int bits_allocated = 16;
  std::uint32_t mask = 0xffff;  // BitsStored
  std::int32_t sign_bit = 0;    // 0 for unsigned data
  std::int32_t shift = 0;       // integer rescale folded into the stored values
  double slope = 1.0, intercept = 0.0;
};

// Decodes the listed frames of one file into their slices of `volume`, one frame at a time into
// `scratch` (one frame, reused): native data is read from the file, compressed data decoded by
// DCMTK's codec straight into it. Nothing else is allocated per file, and the dataset never holds
// a decoded copy (issue 28: that doubled the peak memory of a compressed series, and the fresh
// pages of a decoded copy per file were page faults that kept two threads from scaling).
Status decodeFile(const FileHeader& h, DcmDataset& ds,
                  const std::vector<std::pair<int, int>>& frames, const PixelLayout& L,
                  std::vector<Uint16>& scratch, Volume& volume) {
  const E_TransferSyntax xfer = ds.getOriginalXfer();
  if (xfer == EXS_JPEG2000LosslessOnly || xfer == EXS_JPEG2000 ||
      xfer == EXS_JPEG2000MulticomponentLosslessOnly || xfer == EXS_JPEG2000Multicomponent) {
    return makeError(ErrorCode::kUnsupported,
                     h.path +
                         ": JPEG 2000 pixel data; Debian's DCMTK has no JPEG 2000 "
                         "decoder (convert the series, e.g. with gdcmconv --raw)");
  }
  const std::size_t needed_bytes = L.frame_bytes * static_cast<std::size_t>(h.frames);
  auto truncated = [&](std::size_t have_bytes) {
    return makeError(ErrorCode::kFormat,
                     h.path + ": pixel data holds " + std::to_string(have_bytes) + " bytes, " +
                         std::to_string(needed_bytes) + " expected (truncated or malformed file)");
  };
  const bool encapsulated = DcmXfer(xfer).isEncapsulated();
  DcmElement* pixel_element = nullptr;
  if (ds.findAndGetElement(DCM_PixelData, pixel_element).bad()) return truncated(0);
  auto* pixel_data = dynamic_cast<DcmPixelData*>(pixel_element);  // what DCMTK makes of (7FE0,0010)
  if (encapsulated && pixel_data == nullptr) return truncated(0);
  if (!encapsulated && pixel_element->getLength() < needed_bytes) {
    return truncated(pixel_element->getLength());
  }
  // Frames of one file come in increasing order; DCMTK finds a frame's first fragment from where
  // the previous one ended (needed when the basic offset table is empty).
  Uint32 start_fragment = 0;
  int next_frame = 0;
  DcmFileCache file_cache;  // keeps the file open across this file's frames
  for (const auto& [frame, k] : frames) {
    const std::size_t offset = L.frame_bytes * static_cast<std::size_t>(frame);
    if (encapsulated) {
      if (frame != next_frame) start_fragment = 0;
      OFString colour_model;
      const OFCondition c = pixel_data->getUncompressedFrame(
          &ds, static_cast<Uint32>(frame), start_fragment, scratch.data(),
          static_cast<Uint32>(L.frame_bytes), colour_model, &file_cache);
      if (c == EC_CannotChangeRepresentation) {  // no codec for it here
        return makeError(ErrorCode::kUnsupported, h.path + ": cannot decompress transfer syntax " +
                                                      DcmXfer(xfer).getXferName());
      }
      if (c.bad()) {
        return makeError(ErrorCode::kFormat, h.path + ": frame " + std::to_string(frame + 1) +
                                                 " of " + DcmXfer(xfer).getXferName() +
                                                 " pixel data cannot be decoded (" + c.text() +
                                                 ")");
      }
      next_frame = frame + 1;
    } else if (pixel_element
                   ->getPartialValue(scratch.data(), static_cast<Uint32>(offset),
                                     static_cast<Uint32>(L.frame_bytes), &file_cache,
                                     gLocalByteOrder)
                   .bad()) {
      return truncated(offset);
    }
    const Uint16* raw16 = scratch.data();
    const Uint8* raw8 = reinterpret_cast<const Uint8*>(scratch.data());  // char-typed view
    std::int16_t* out = volume.voxels.data() + L.plane * static_cast<std::size_t>(k);
    const auto [lo, hi] = L.bits_allocated == 8
                              ? convertFrame(raw8, out, L.plane, L.mask, L.sign_bit, L.shift)
                              : convert16(raw16, out, L.plane, L.mask, L.sign_bit, L.shift);
    if (lo < INT16_MIN || hi > INT16_MAX) {
      const double worst = (hi > INT16_MAX ? hi : lo) - L.shift;
      return makeError(ErrorCode::kUnsupported, h.path + ": value " +
                                                    describeNum(worst * L.slope + L.intercept) +
                                                    " does not fit the int16 voxel store");
    }
  }
  return Ok{};
}

}  // namespace

Expected<DicomLoadResult> readDicomSeries(const std::vector<std::string>& paths,
                                          const DicomLoadOptions& options) {
  registerDecodersOnce();
  auto progress = [&](const char* stage, std::size_t done, std::size_t total) {
    if (options.progress) options.progress(Progress{stage, done, total});
  };
  DicomLoadResult result;
  Status walk = Ok{};
  const std::vector<std::string> files = collectFiles(paths, result.notes, walk);
  if (!walk) return walk.error();
  if (files.empty()) return makeError(ErrorCode::kIo, "no files found in the given paths");

  // Pass 1: headers. The parsed datasets are kept: DCMTK leaves large values (the pixel data) on
  // disk until asked, so pass 2 reads pixels without parsing any file again.
  std::vector<FileHeader> headers;
  std::vector<std::unique_ptr<DcmFileFormat>> datasets;
  std::map<std::string, std::vector<std::size_t>> by_series;
  for (std::size_t i = 0; i < files.size(); ++i) {
    progress("scan", i, files.size());
    auto ff = std::make_unique<DcmFileFormat>();
    const OFCondition c = ff->loadFile(files[i].c_str());
    if (c.bad()) {
      result.notes.push_back(files[i] + ": skipped, not readable as DICOM (" + c.text() + ")");
      continue;
    }
    std::string skip;
    auto h = readHeader(files[i], *ff, skip);
    if (!h) {
      result.notes.push_back(files[i] + ": skipped, " + (skip.empty() ? h.error().message : skip));
      continue;
    }
    by_series[h->series_uid].push_back(headers.size());
    headers.push_back(std::move(h).value());
    datasets.push_back(std::move(ff));
  }
  progress("scan", files.size(), files.size());

  for (const auto& [uid, members] : by_series) {
    DicomSeriesSummary s;
    s.uid = uid;
    s.modality = headers[members.front()].modality;
    s.description = headers[members.front()].description;
    s.files = members.size();
    for (std::size_t m : members)
      s.frames += static_cast<std::size_t>(headers[m].frames);
    result.series.push_back(s);
  }
  std::stable_sort(result.series.begin(), result.series.end(),
                   [](const auto& a, const auto& b) { return a.frames > b.frames; });
  if (result.series.empty()) {
    std::string why = "no DICOM image series found in " + std::to_string(files.size()) + " files";
    if (!result.notes.empty()) why += " (first: " + result.notes.front() + ")";
    return makeError(ErrorCode::kFormat, why);
  }

  // Choose the series.
  std::string uid = options.series_uid;
  if (uid.empty()) {
    auto ct = std::find_if(result.series.begin(), result.series.end(),
                           [](const auto& s) { return s.modality == "CT"; });
    uid = ct != result.series.end() ? ct->uid : result.series.front().uid;
    if (ct == result.series.end()) {
      result.warnings.push_back("no CT series found; using the largest image series (" +
                                result.series.front().modality + ", " + uid + ")");
    }
  } else if (by_series.count(uid) == 0) {
    std::string list;
    for (const auto& s : result.series)
      list += (list.empty() ? "" : ", ") + s.uid;
    return makeError(ErrorCode::kInvalidArgument,
                     "series " + uid + " not found; series present: " + list);
  }
  const std::vector<std::size_t>& members = by_series[uid];
  const FileHeader& ref = headers[members.front()];
  if (auto ok = checkPixelFormat(ref); !ok) return ok.error();
  for (std::size_t m : members) {
    if (auto ok = checkConsistent(ref, headers[m]); !ok) return ok.error();
  }

  // Order frames along the slice normal.
  const Eigen::Vector3d normal = ref.row_dir.cross(ref.col_dir);
  std::vector<Frame> frames;
  for (std::size_t m : members) {
    for (int f = 0; f < headers[m].frames; ++f) {
      frames.push_back({m, f, normal.dot(headers[m].frame_positions[static_cast<std::size_t>(f)])});
    }
  }
  std::stable_sort(frames.begin(), frames.end(), [](const Frame& a, const Frame& b) {
    return a.along_normal_mm < b.along_normal_mm;
  });
  auto where = [&](const Frame& f) {
    const FileHeader& h = headers[f.file];
    return h.frames > 1 ? h.path + " frame " + std::to_string(f.frame + 1) : h.path;
  };
  auto position = [&](const Frame& f) {
    return headers[f.file].frame_positions[static_cast<std::size_t>(f.frame)];
  };

  // Slice spacing: one regular step, or whole multiples of it (missing slices).
  double step = ref.slice_thickness > 0.0 ? ref.slice_thickness : 1.0;
  std::vector<int> slot(frames.size(), 0);  // index k of each frame
  if (frames.size() == 1 && ref.slice_thickness <= 0.0) {
    result.warnings.push_back("single slice without SliceThickness; slice spacing set to 1 mm");
  }
  if (frames.size() > 1) {
    std::vector<double> gaps;
    for (std::size_t i = 1; i < frames.size(); ++i) {
      const double gap = frames[i].along_normal_mm - frames[i - 1].along_normal_mm;
      if (gap < 1e-3) {
        return makeError(ErrorCode::kFormat, "duplicate slice position " +
                                                 describeNum(frames[i].along_normal_mm) +
                                                 " mm along the normal: " + where(frames[i - 1]) +
                                                 " and " + where(frames[i]));
      }
      gaps.push_back(gap);
    }
    std::vector<double> sorted = gaps;
    std::nth_element(sorted.begin(), sorted.begin(), sorted.end());
    step = sorted.front();  // the smallest gap is the true spacing when slices are missing
    for (std::size_t i = 1; i < frames.size(); ++i) {
      const double ratio = gaps[i - 1] / step;
      const double whole = std::round(ratio);
      if (std::abs(ratio - whole) > 0.02 * whole) {
        return makeError(ErrorCode::kFormat,
                         "uneven slice spacing: " + describeNum(gaps[i - 1]) + " mm between " +
                             where(frames[i - 1]) + " and " + where(frames[i]) +
                             " where the series' spacing is " + describeNum(step) + " mm");
      }
      const int missing = static_cast<int>(whole) - 1;
      if (missing > 0) {
        const std::string gap_text = std::to_string(missing) + " missing slice(s) (gap " +
                                     describeNum(gaps[i - 1]) + " mm) between " +
                                     where(frames[i - 1]) + " and " + where(frames[i]);
        if (!options.fill_missing_slices) {
          return makeError(ErrorCode::kFormat,
                           gap_text + "; load with fill_missing_slices to interpolate them");
        }
        result.warnings.push_back(gap_text + ": filled by linear interpolation");
      }
      slot[i] = slot[i - 1] + static_cast<int>(whole);
    }
    // All slices must lie on one line along the normal (no gantry tilt / shear).
    const Eigen::Vector3d first = position(frames.front());
    for (const Frame& f : frames) {
      const Eigen::Vector3d d = position(f) - first;
      const double shear = (d - normal.dot(d) * normal).norm();
      if (shear > 0.01 * std::min(ref.row_spacing, ref.col_spacing) + 1e-3) {
        return makeError(ErrorCode::kUnsupported,
                         where(f) + " is shifted " + describeNum(shear) +
                             " mm in-plane from the first slice (gantry tilt or sheared "
                             "series); such series need resampling, which ignav does not guess");
      }
    }
  }

  Volume& vol = result.volume;
  Geometry& g = vol.geometry;
  g.dims = {ref.cols, ref.rows, slot.back() + 1};
  g.spacing_mm = {ref.col_spacing, ref.row_spacing, step};
  g.origin_lps_mm = position(frames.front());
  g.direction.col(0) = ref.row_dir;
  g.direction.col(1) = ref.col_dir;
  g.direction.col(2) = normal;
  if (auto ok = g.validate(ref.path); !ok) return ok.error();
  vol.modality = ref.modality;
  vol.series_uid = uid;
  vol.frame_of_reference_uid = ref.frame_of_reference_uid;
  vol.study_uid = ref.study_uid;
  vol.patient_name = ref.patient_name;
  vol.patient_id = ref.patient_id;
  vol.description = ref.description;

  // Storage: HU directly when the rescale is an integer shift, else raw with scale/offset.
  const bool shift_only = ref.slope == 1.0 && ref.intercept == std::round(ref.intercept);
  if (shift_only) {
    vol.value_scale = 1.0;
    vol.value_offset = 0.0;
  } else {
    vol.value_scale = ref.slope;
    vol.value_offset = ref.intercept;
  }
  const double shift = shift_only ? ref.intercept : 0.0;
  vol.voxels.resize(g.voxelCount());  // uninitialised: every slot is written below

  // Which frames of which file go to which slice k.
  const std::size_t plane = static_cast<std::size_t>(ref.rows) * static_cast<std::size_t>(ref.cols);
  std::vector<std::vector<std::pair<int, int>>> frames_of_file(headers.size());  // (frame, k)
  for (std::size_t i = 0; i < frames.size(); ++i) {
    frames_of_file[frames[i].file].push_back({frames[i].frame, slot[i]});
  }
  const int bits = ref.bits_stored;
  const bool is_signed = ref.pixel_representation == 1;
  const std::uint32_t mask = bits >= 32 ? 0xffffffffu : ((1u << bits) - 1u);
  PixelLayout layout;
  layout.plane = plane;
  layout.frame_bytes = plane * static_cast<std::size_t>(ref.bits_allocated / 8);
  layout.bits_allocated = ref.bits_allocated;
  layout.mask = mask;
  layout.sign_bit = is_signed ? std::int32_t{1} << (bits - 1) : 0;
  layout.shift = static_cast<std::int32_t>(shift);
  layout.slope = ref.slope;
  layout.intercept = ref.intercept;
  // Pass 2, in parallel: files are taken in order from a shared counter; each worker has its own
  // frame buffer and writes disjoint slices. The first failing file in order is reported, so the
  // result does not depend on timing. Only the calling thread reports progress.
  const std::size_t workers = std::min<std::size_t>(
      members.size(), options.threads > 0
                          ? static_cast<std::size_t>(options.threads)
                          : std::clamp(std::thread::hardware_concurrency(), 1u, 8u));
  std::atomic<std::size_t> next_file{0}, frames_done{0};
  std::atomic<bool> failed{false};
  std::mutex error_mutex;
  std::size_t error_index = members.size();
  Error first_error;
  auto work = [&](bool report) {
    std::vector<Uint16> scratch((layout.frame_bytes + 1) / 2);  // one native frame, reused
    for (std::size_t i = next_file++; i < members.size() && !failed; i = next_file++) {
      const std::size_t m = members[i];
      Status ok = decodeFile(headers[m], *datasets[m]->getDataset(), frames_of_file[m], layout,
                             scratch, vol);
      // Done with this file: its parsed header and fragments go now (each file is one worker's).
      datasets[m].reset();
      if (!ok) {
        const std::lock_guard<std::mutex> lock(error_mutex);
        if (i < error_index) {
          error_index = i;
          first_error = ok.error();
        }
        failed = true;
      }
      frames_done += frames_of_file[m].size();
      if (report) progress("decode", frames_done, frames.size());
    }
  };
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < workers; ++t)
    pool.emplace_back(work, false);
  work(true);
  for (auto& t : pool)
    t.join();
  if (failed) return first_error;
  progress("decode", frames.size(), frames.size());

  // Interpolate the missing slices the caller allowed.
  for (std::size_t i = 1; i < frames.size(); ++i) {
    const int k0 = slot[i - 1], k1 = slot[i];
    for (int k = k0 + 1; k < k1; ++k) {
      const double t = static_cast<double>(k - k0) / (k1 - k0);
      const std::int16_t* a = vol.voxels.data() + plane * static_cast<std::size_t>(k0);
      const std::int16_t* b = vol.voxels.data() + plane * static_cast<std::size_t>(k1);
      std::int16_t* out = vol.voxels.data() + plane * static_cast<std::size_t>(k);
      for (std::size_t p = 0; p < plane; ++p) {
        out[p] = static_cast<std::int16_t>(std::lround((1.0 - t) * a[p] + t * b[p]));
      }
    }
  }
  return result;
}

}  // namespace ignav::volume
