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

echo "== the paper's IK simulation, closed form vs exact (writes figures)"
"$plan" study --robot "$robot" --out-dir "$out" > "$out/study.json"
echo
echo "Session folder: $out/"
ls -1 "$out"
echo "Open feasible_volume.ply in 3D Slicer or ParaView; IK_STUDY.md and the PNGs in any viewer."
