#!/usr/bin/env bash
# The README's main job: install, build, and plan on the bundled paper instrument, leaving a
# session folder (out/demo/) with artifacts a person can open.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
bash tools/build.sh
robot=configs/robots/torabi2014.yaml
plan=build/tools/ignav-plan/ignav-plan
out=out/demo
rm -rf "$out" && mkdir -p "$out"

echo "== feasible volume of $robot"
"$plan" workspace --robot "$robot" --grid-mm 0.5 --ply "$out/feasible_volume.ply" | tee "$out/workspace.json"

echo "== targets (robot frame, mm): joints, motor steps, closed-form error"
cat > "$out/targets.jsonl" <<'JSONL'
{"id": "T1", "ik": [5.0, 12.0, -165.0]}
{"id": "T2", "ik": [-14.0, 3.0, -180.0]}
{"id": "T3", "ik": [0.0, -22.0, -195.0]}
{"id": "near-axis", "ik": [0.5, 0.5, -150.0]}
{"id": "too-far", "ik": [30.0, 0.0, -180.0]}
{"id": "home", "fk": [0, 0, 0]}
JSONL
"$plan" batch --robot "$robot" --in "$out/targets.jsonl" | tee "$out/plan.jsonl"

echo "== the built-in phantom CT: a DICOM series, read back, and slices through its fiducials"
"$plan" phantom "$out/phantom_ct" --noise-hu 8 > "$out/phantom.json"
"$plan" volume-info "$out/phantom_ct" --probe-lps -12,-6,-18 | tee "$out/volume_info.json"
"$plan" render "$out/phantom_ct" --view axial --lps -12,-6,-18 --window 2000 --level 300 --size 512 --pixel-mm 0.16 \
  --mark -12,-6,-18 --mark 14,-4,6 --mark 2,16,20 --out "$out/slice_axial_F1.png" > "$out/slice_axial_F1.json"
"$plan" render "$out/phantom_ct" --view coronal --lps 14,-4,6 --window 2000 --level 300 --size 512 --pixel-mm 0.16 \
  --mark -12,-6,-18 --mark 14,-4,6 --mark 2,16,20 --out "$out/slice_coronal_F2.png" > "$out/slice_coronal_F2.json"
"$plan" render "$out/phantom_ct" --view sagittal --lps 2,16,20 --window 2000 --level 300 --size 512 --pixel-mm 0.16 \
  --mark -12,-6,-18 --mark 14,-4,6 --mark 2,16,20 --out "$out/slice_sagittal_F3.png" > "$out/slice_sagittal_F3.json"

echo "== the paper's IK simulation, closed form vs exact (writes figures)"
"$plan" study --robot "$robot" --out-dir "$out" > "$out/study.json"
echo
echo "Session folder: $out/"
ls -1 "$out"
echo "Open phantom_ct/ (DICOM) and feasible_volume.ply in 3D Slicer or ParaView; the slice PNGs"
echo "(with their pixel -> LPS mapping in the matching .json) and IK_STUDY.md in any viewer."
