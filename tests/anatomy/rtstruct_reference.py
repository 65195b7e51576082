#!/usr/bin/python3
"""Third-party references for the RT Structure Set reader (tests/anatomy/dicom_structures_test).

  make OUT FRAME_UID GRID_JSON       writes, with pydicom, an RT Structure Set of shapes with known
                                     areas (a ring with a hole, two islands per slice, a concave
                                     star, a sphere, a point) drawn on the grid's slices
  make-crossing OUT FRAME_UID GRID   the same with the star's middle contour a bow tie (crossing
                                     itself at the star's centre)
  volumes RTSTRUCT GRID_JSON         prints {ROI name: volume in cm3} as dicompyler-core computes
                                     it (its DVH's volume over an RT Dose that covers the grid)

GRID_JSON: {"origin": [x, y, z], "spacing": [sx, sy, sz], "dims": [ni, nj, nk]}, axes along LPS.
Run with Debian's /usr/bin/python3 (python3-pydicom, python3-dicompylercore).
"""
import json
import math
import sys

import numpy as np
import pydicom
from pydicom.dataset import Dataset, FileMetaDataset
from pydicom.sequence import Sequence
from pydicom.uid import ExplicitVRLittleEndian, generate_uid

RT_STRUCT = "1.2.840.10008.5.1.4.1.1.481.3"
RT_DOSE = "1.2.840.10008.5.1.4.1.1.481.2"


def circle(cx, cy, r, n=96, clockwise=False):
    pts = []
    for m in range(n):
        a = 2 * math.pi * m / n * (-1 if clockwise else 1)
        pts.append((cx + r * math.cos(a), cy + r * math.sin(a)))
    return pts


def star(cx, cy, r_out, r_in, spikes=7):
    pts = []
    for m in range(2 * spikes):
        r = r_out if m % 2 == 0 else r_in
        a = math.pi * m / spikes
        pts.append((cx + r * math.cos(a), cy + r * math.sin(a)))
    return pts


def shapes(grid):
    """ROI name -> (colour, [(z, [(x, y), ...]), ...]) on the grid's slices."""
    oz, sz, nk = grid["origin"][2], grid["spacing"][2], grid["dims"][2]
    zs = [oz + k * sz for k in range(nk)]
    ring, islands, concave, ball = [], [], [], []
    for z in zs:
        if -12 <= z <= 12:
            ring.append((z, circle(5.3, -3.1, 20.0)))
            ring.append((z, circle(5.3, -3.1, 8.0, clockwise=True)))  # the hole
            islands.append((z, circle(-29.7, 20.2, 6.0)))
            islands.append((z, circle(-12.4, 20.6, 6.0)))
        if -6 <= z <= 14:
            concave.append((z, star(-20.3, -18.9, 12.0, 5.0)))
        if abs(z - 1.0) < 14.0:
            ball.append((z, circle(22.2, 21.7, math.sqrt(14.0**2 - (z - 1.0) ** 2))))
    return {
        "ring": ([255, 128, 0], ring),
        "islands": ([0, 160, 255], islands),
        "star": ([200, 40, 200], concave),
        "ball": ([40, 200, 40], ball),
    }


def make(out, frame_uid, grid, crossing=False):
    ds = Dataset()
    ds.file_meta = FileMetaDataset()
    ds.file_meta.MediaStorageSOPClassUID = RT_STRUCT
    ds.file_meta.MediaStorageSOPInstanceUID = generate_uid()
    ds.file_meta.TransferSyntaxUID = ExplicitVRLittleEndian
    ds.SOPClassUID = RT_STRUCT
    ds.SOPInstanceUID = ds.file_meta.MediaStorageSOPInstanceUID
    ds.Modality = "RTSTRUCT"
    ds.PatientName = "IGNAV^TEST"
    ds.PatientID = "TEST"
    ds.StudyInstanceUID = generate_uid()
    ds.SeriesInstanceUID = generate_uid()
    ds.StructureSetLabel = "shapes"
    ref = Dataset()
    ref.FrameOfReferenceUID = frame_uid
    ds.ReferencedFrameOfReferenceSequence = Sequence([ref])
    rois, contours, observations = [], [], []
    drawn = shapes(grid)
    if crossing:
        planes = drawn["star"][1]
        z, _ = planes[len(planes) // 2]
        cx, cy = -20.3, -18.9
        planes[len(planes) // 2] = (z, [(cx - 8, cy - 8), (cx + 8, cy + 8), (cx + 8, cy - 8), (cx - 8, cy + 8)])
    for number, (name, (colour, planes)) in enumerate(drawn.items(), start=1):
        roi = Dataset()
        roi.ROINumber = number
        roi.ReferencedFrameOfReferenceUID = frame_uid
        roi.ROIName = name
        roi.ROIGenerationAlgorithm = "MANUAL"
        rois.append(roi)
        rc = Dataset()
        rc.ReferencedROINumber = number
        rc.ROIDisplayColor = colour
        seq = []
        for z, pts in planes:
            c = Dataset()
            c.ContourGeometricType = "CLOSED_PLANAR"
            c.NumberOfContourPoints = len(pts)
            c.ContourData = [f"{v:.4f}" for x, y in pts for v in (x, y, z)]
            seq.append(c)
        rc.ContourSequence = Sequence(seq)
        contours.append(rc)
        obs = Dataset()
        obs.ObservationNumber = number
        obs.ReferencedROINumber = number
        obs.RTROIInterpretedType = "ORGAN"
        obs.ROIInterpreter = ""
        observations.append(obs)
    # A marker: points only, which is no volume.
    point_number = len(rois) + 1
    roi = Dataset()
    roi.ROINumber = point_number
    roi.ReferencedFrameOfReferenceUID = frame_uid
    roi.ROIName = "marker"
    roi.ROIGenerationAlgorithm = "MANUAL"
    rois.append(roi)
    rc = Dataset()
    rc.ReferencedROINumber = point_number
    rc.ROIDisplayColor = [255, 255, 0]
    c = Dataset()
    c.ContourGeometricType = "POINT"
    c.NumberOfContourPoints = 1
    c.ContourData = ["0.0", "0.0", f"{grid['origin'][2]:.4f}"]
    rc.ContourSequence = Sequence([c])
    contours.append(rc)
    ds.StructureSetROISequence = Sequence(rois)
    ds.ROIContourSequence = Sequence(contours)
    ds.RTROIObservationsSequence = Sequence(observations)
    pydicom.dcmwrite(out, ds, write_like_original=False)


def dose_over(grid):
    """A uniform RT Dose whose voxels are the grid's (dicompyler-core rasterises on them)."""
    nx, ny, nz = grid["dims"]
    d = Dataset()
    d.file_meta = FileMetaDataset()
    d.file_meta.TransferSyntaxUID = ExplicitVRLittleEndian
    d.is_little_endian, d.is_implicit_VR = True, False
    d.SOPClassUID = RT_DOSE
    d.Modality = "RTDOSE"
    d.ImagePositionPatient = list(grid["origin"])
    d.ImageOrientationPatient = [1, 0, 0, 0, 1, 0]
    d.PixelSpacing = [grid["spacing"][1], grid["spacing"][0]]
    d.Rows, d.Columns, d.NumberOfFrames = ny, nx, nz
    d.GridFrameOffsetVector = [k * grid["spacing"][2] for k in range(nz)]
    d.SamplesPerPixel = 1
    d.PhotometricInterpretation = "MONOCHROME2"
    d.BitsAllocated, d.BitsStored, d.HighBit, d.PixelRepresentation = 16, 16, 15, 0
    d.DoseGridScaling = 0.01
    d.DoseUnits, d.DoseType, d.DoseSummationType = "GY", "PHYSICAL", "PLAN"
    d.PixelData = np.full((nz, ny, nx), 100, dtype="<u2").tobytes()
    return d


def volumes(rtstruct, grid):
    from dicompylercore import dicomparser, dvhcalc

    ss = pydicom.dcmread(rtstruct, force=True)
    dose = dose_over(grid)
    out = {}
    for number, s in dicomparser.DicomParser(ss).GetStructures().items():
        planes = dicomparser.DicomParser(ss).GetStructureCoordinates(number)
        if not planes or any(c["type"] != "CLOSED_PLANAR" for p in planes.values() for c in p):
            continue
        dvh = dvhcalc.get_dvh(ss, dose, number, thickness=grid["spacing"][2])
        out[s["name"]] = float(dvh.volume)
    print(json.dumps(out))


if __name__ == "__main__":
    if sys.argv[1] in ("make", "make-crossing"):
        make(sys.argv[2], sys.argv[3], json.loads(sys.argv[4]), sys.argv[1] == "make-crossing")
    elif sys.argv[1] == "volumes":
        volumes(sys.argv[2], json.loads(sys.argv[3]))
    else:
        sys.exit(__doc__)
