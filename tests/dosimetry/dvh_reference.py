#!/usr/bin/python3
"""A third-party reference for ignav's dose-volume histograms (tests/dosimetry/rt_dose_test).

  dvh RTSTRUCT RTDOSE RX_GY [NAME,...]
                              prints {ROI name: {"volume_cm3", "d90_gy", "v100"}} as
                              dicompyler-core computes them from the two files: its cumulative
                              DVH of each closed planar ROI on the dose grid, D90 (the dose 90 %
                              of the ROI receives) and V100 (the fraction receiving RX_GY or more);
                              of the ROIs named only, when names are given

Run with Debian's /usr/bin/python3 (python3-pydicom, python3-dicompylercore).
"""
import json
import sys

import pydicom
from dicompylercore import dicomparser, dvhcalc


def dvh(rtstruct, rtdose, rx_gy, names=None):
    ss = pydicom.dcmread(rtstruct, force=True)
    dose = pydicom.dcmread(rtdose, force=True)
    parser = dicomparser.DicomParser(ss)
    out = {}
    for number, s in parser.GetStructures().items():
        if names is not None and s["name"] not in names:
            continue
        planes = parser.GetStructureCoordinates(number)
        if not planes or any(c["type"] != "CLOSED_PLANAR" for p in planes.values() for c in p):
            continue
        h = dvhcalc.get_dvh(ss, dose, number)
        out[s["name"]] = {
            "volume_cm3": float(h.volume),
            "d90_gy": float(h.dose_constraint(90).value),
            "v100": float(h.volume_constraint(rx_gy, "Gy").value) / float(h.volume),
        }
    print(json.dumps(out))


if __name__ == "__main__":
    if len(sys.argv) in (5, 6) and sys.argv[1] == "dvh":
        dvh(sys.argv[2], sys.argv[3], float(sys.argv[4]),
            sys.argv[5].split(",") if len(sys.argv) == 6 else None)
    else:
        sys.exit(__doc__)
