#!/usr/bin/python3
"""A third-party reader for ignav's RT Plans (tests/dosimetry/rt_plan_test, the workflow's dose).

  plan RTPLAN   prints what pydicom reads from the plan as JSON: its SOP class, modality,
                technique and type, the source (isotope, half-life in days, air-kerma rate,
                active length in mm, model), the prescription, the referenced structure set and
                each channel's seed position (its control points' 3D position, mm)

Run with Debian's /usr/bin/python3 (python3-pydicom).
"""
import json
import sys

import pydicom


def plan(path):
    ds = pydicom.dcmread(path)
    source = ds.SourceSequence[0]
    setup = ds.ApplicationSetupSequence[0]
    seeds = []
    for channel in setup.ChannelSequence:
        points = [list(map(float, p.ControlPoint3DPosition)) for p in channel.BrachyControlPointSequence]
        seeds.append(points[0])
        assert all(p == points[0] for p in points), "a seed's control points differ"
    out = {
        "sop_class": str(ds.SOPClassUID),
        "modality": ds.Modality,
        "technique": ds.BrachyTreatmentTechnique,
        "type": ds.BrachyTreatmentType,
        "isotope": source.SourceIsotopeName,
        "half_life_days": float(source.SourceIsotopeHalfLife),
        "air_kerma_rate": float(source.ReferenceAirKermaRate),
        "active_length_mm": float(source.ActiveSourceLength),
        "model": str(source.get("SourceModelID", "")),
        "prescription_gy": float(ds.DoseReferenceSequence[0].TargetPrescriptionDose),
        "frame_of_reference": str(ds.FrameOfReferenceUID),
        "structure_set": str(ds.ReferencedStructureSetSequence[0].ReferencedSOPInstanceUID)
        if "ReferencedStructureSetSequence" in ds else "",
        "seeds": seeds,
    }
    print(json.dumps(out))


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "plan":
        plan(sys.argv[2])
    else:
        sys.exit(__doc__)
