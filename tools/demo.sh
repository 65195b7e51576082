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

echo "== DDS Security: a test CA and an identity per role (configs/security/make-test-pki.sh)"
configs/security/make-test-pki.sh "$out/pki"

echo "== the server, the built-in phantom and the scripted client (configs/demo/plan.yaml)"
session="$out/session"
server_log="$out/server.log"
# OpenIGTLink on a free port (IGNAV_IGTL_PORT=18944 for a 3D Slicer with IGNAV_DEMO_KEEP=1).
build/server/ignav-server --config configs/server.yaml --session-dir "$session" \
  --identity "$out/pki/service" --igtl-port "${IGNAV_IGTL_PORT:-0}" \
  > "$out/server.ready" 2> "$server_log" &
server_pid=$!
trap 'kill $server_pid 2>/dev/null || true' EXIT
for _ in $(seq 100); do grep -q "ready" "$out/server.ready" 2>/dev/null && break; sleep 0.1; done
cat "$out/server.ready"

echo "== the web viewer (docs/WEB.md): the same workflow, live in a browser"
# As the viewer role: a browser can watch, page through slices and press emergency stop, while the
# scripted client below plans and approves. (Run a gateway with a planner or approver identity to
# click targets and approve from the browser.)
build/tools/ignav-web/ignav-web --dds-config configs/dds/loopback.xml --port "${IGNAV_WEB_PORT:-0}" \
  --identity "$out/pki/viewer" --client-id web-viewer > "$out/web.ready" 2> "$out/web.log" &
web_pid=$!
trap 'kill $server_pid $web_pid 2>/dev/null || true' EXIT
for _ in $(seq 100); do grep -q "ready" "$out/web.ready" 2>/dev/null && break; sleep 0.1; done
web_url=$(sed -n 's/.*url=\([^ ]*\).*/\1/p' "$out/web.ready")
echo "web viewer: $web_url  (open it in a browser while the demo runs; IGNAV_DEMO_KEEP=1 keeps it up)"
# The scripted client is the operator (configs/server.yaml approval.approvers), authenticated with
# the approver identity: it may plan and approve. Every command is encrypted on the wire.
ctl="build/tools/ignavctl/ignavctl --dds-config configs/dds/loopback.xml --identity $out/pki/approver"
ctl="$ctl --client-id operator"
# The servers on the domain (docs/DEPLOYMENT.md): one robot here, so ignavctl needs no --robot.
$ctl robots | tee "$session/robots.txt"
$ctl run configs/demo/plan.yaml --out-dir "$session"
echo
$ctl status
echo
$ctl structures ls | tee "$session/structures.txt"
$ctl targets ls | tee "$session/summary.txt"
$ctl motion | tee -a "$session/summary.txt"
echo

echo "== the closed loop (docs/VERIFICATION.md): confirmation CT, errors, a fitted tissue, a compensated pass"
# The world: seeds where a gel the server is not told (configs/demo/hidden_tissue.yaml) deflected
# the needle, with the CT's noise and partial volume. The server measures them on its own.
hidden="--hidden-tissue phantom_gel --tissues configs/demo/hidden_tissue.yaml --noise-hu 8"
# shellcheck disable=SC2086
"$plan" confirmation-phantom "$session" --robot "$robot" --out "$out/confirmation_1" $hidden
$ctl verify load "$PWD/$out/confirmation_1" | tee "$session/verification_1.txt"
$ctl verify fit phantom_gel_fitted
$ctl run configs/demo/compensated.yaml --out-dir "$session"
# shellcheck disable=SC2086
"$plan" confirmation-phantom "$session" --robot "$robot" --out "$out/confirmation_2" $hidden
$ctl verify load "$PWD/$out/confirmation_2" | tee "$session/verification_2.txt"
python3 - "$session" <<'PY'
import re, sys
# Each pass's error by planned point (robot mm): the first pass also went to two proposed targets,
# the second only to the three clicked points; compare over the points both went to.
row = re.compile(r"^T\d+\s+#\d+\s+\(([^)]*)\)\s+\([^)]*\)\s+([0-9.]+)", re.M)
def errors(i):
    text = open(f"{sys.argv[1]}/verification_{i}.txt").read()
    return {tuple(round(float(x), 1) for x in m[1].split(",")): float(m[2]) for m in row.finditer(text)}
first, second = errors(1), errors(2)
both = sorted(set(first) & set(second))
mean = [sum(e[p] for p in both) / len(both) for e in (first, second)]
print(f"in the extended-bicycle world (the server's own model agreeing with itself): mean "
      f"targeting error at the {len(both)} points both passes went to {mean[0]:.2f} mm as planned, "
      f"{mean[1]:.2f} mm aimed for the fitted tissue")
PY
# The needle left in at the second pass's first target: it runs through the robot's markers on
# its axis, so the scan goes with the session's registration (same-frame); its stylet's tip is
# measured in place of a seed, with the needle's path.
needle_at=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["targets"][0]["id"])' \
  "$out/confirmation_2_truth.json")
# shellcheck disable=SC2086
"$plan" confirmation-phantom "$session" --robot "$robot" --out "$out/confirmation_3" $hidden \
  --needle-at "$needle_at"
$ctl verify load "$PWD/$out/confirmation_3" same-frame | tee "$session/verification_3.txt"
# A world the server does not model (configs/worlds/layered_gel.yaml: elastic rods in layered
# tissue, drag, twist, play, luck per insertion): the same targets' seeds there, measured by the
# server, and a fit it refuses when the model explains nothing (docs/VERIFICATION.md, "Two worlds").
"$plan" confirmation-phantom "$session" --robot "$robot" --out "$out/confirmation_rod" \
  --world configs/worlds/layered_gel.yaml --noise-hu 8
echo "(the second pass's joints were aimed for the gel fitted above: in this world that aim is wrong)"
$ctl verify load "$PWD/$out/confirmation_rod" | tee "$session/verification_rod.txt"
$ctl verify fit layered_gel_fitted 2>&1 | tee "$session/fit_rod.txt" || true
echo "== re-planning mid-insertion in that world (docs/VERIFICATION.md): stop, scan, re-aim, finish"
# One target aimed as planned, stopped with 12 mm of stylet out; the world's intermittent CT of
# the needle there (with its answer for finishing as aimed); the server searches it, refits and
# re-aims on its job thread; the approval shows nominal, previous and re-aimed joints.
$ctl run configs/demo/replan.yaml --out-dir "$session"
rod="--world configs/worlds/layered_gel.yaml --noise-hu 8"
paused=$($ctl --json targets ls | python3 -c 'import json,sys; s=sys.stdin.read(); t=json.loads(s[s.find("{"):]); print(next(v["id"] for v in t.values() if v.get("paused")))')
# shellcheck disable=SC2086
"$plan" confirmation-phantom "$session" --robot "$robot" --out "$out/intermittent_rod" $rod \
  --needle-at "$paused"
$ctl verify scan "$PWD/$out/intermittent_rod" same-frame | tee "$session/replan_scan.txt"
$ctl verify reaim
$ctl approval | tee "$session/replan_approval.txt"
$ctl run configs/demo/finish.yaml --out-dir "$session"
# shellcheck disable=SC2086
"$plan" confirmation-phantom "$session" --robot "$robot" --out "$out/confirmation_replan" $rod
$ctl verify load "$PWD/$out/confirmation_replan" | tee "$session/verification_replan.txt"
python3 - "$out" "$paused" <<'PY'
import json, sys
out, paused = sys.argv[1], int(sys.argv[2])
aimed = [t for t in json.load(open(f"{out}/intermittent_rod_truth.json"))["targets"] if t["id"] == paused][0]
landed = [t for t in json.load(open(f"{out}/confirmation_replan_truth.json"))["targets"] if t["id"] == paused][0]
print(f"in the rod world: T{paused} would have landed {aimed['finished_off_plan_mm']:.2f} mm off as "
      f"aimed; re-aimed from its needle's path it landed {landed['landing_off_plan_mm']:.2f} mm off "
      f"(the world's truth; the server's measurement is above)")
PY
echo "== the seeds' dose (docs/DOSIMETRY.md): re-planned from what was implanted, TG-43U1"
$ctl run configs/demo/seeds.yaml --out-dir "$session" | tee "$session/seed_plan.txt"
$ctl structures ls | awk '/^robot placement/ {p = 0} /^dose / {p = 1} p' | tee "$session/dose.txt"
echo "== what compensation buys in each world, 24 targets (ignav-plan world-study)"
"$plan" world-study | tee "$session/world_study.md"
echo
echo "== what 3D Slicer sees over OpenIGTLink (docs/OPENIGTLINK.md): workphase, registration, tip"
igtl_port=$(sed -n 's/.*igtl_port=\([0-9]*\).*/\1/p' "$out/server.ready")
if [ -n "$igtl_port" ]; then
  build/tools/ignav-igtl/ignav-igtl --port "$igtl_port" get-status get:ImageToRobot \
    get:NeedleTipToImage | tee "$session/openigtlink.jsonl"
else
  echo "(no OpenIGTLink bridge: see $server_log)"
fi
# What a browser shows at the end of the session, as a picture in the session folder.
node tools/ignav-web/screenshot.mjs --url "$web_url" --out "$session/web_viewer.png" \
  --chromium "$(command -v chromium)" || echo "(no screenshot of the web viewer)"
if [ "${IGNAV_DEMO_KEEP:-0}" = 1 ]; then
  echo "server and web viewer stay up: $web_url  (Ctrl-C ends them)"
  wait $server_pid || true
fi
kill -TERM $web_pid && wait $web_pid || true
kill -TERM $server_pid && wait $server_pid
trap - EXIT
echo "server stopped cleanly; its log: $server_log"

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

echo "== the built-in phantom CT: the robot inclined in gelatin, bead markers at its three feature points"
"$plan" phantom "$out/phantom_ct" --robot "$robot" --oblique --noise-hu 8 > "$out/phantom.json"
"$plan" volume-info "$out/phantom_ct" | tee "$out/volume_info.json"

echo "== registration: find the markers, match them to the robot's feature points, register"
"$plan" find-fiducials "$out/phantom_ct" --robot "$robot" --tfm "$out/image_to_robot.tfm" \
  --markups "$out/fiducials.mrk.json" | tee "$out/fiducials.json"
# The same by hand: the three points as a user would click them (to 0.5 mm), with the expected
# TRE at two targets.
python3 - "$out" <<'PY'
import json, sys
out = sys.argv[1]
truth = json.load(open(f"{out}/phantom.json"))["fiducials_lps_mm"]
json.dump({"image_mm": [[round(c * 2) / 2 for c in p] for p in truth]},
          open(f"{out}/clicked_points.json", "w"))
PY
"$plan" register --pairs "$out/clicked_points.json" --robot "$robot" --tre 0,0,0 --tre 10,-20,-40 \
  --markups "$out/clicked_points.mrk.json" | tee "$out/registration_clicked.json"

echo "== slices through the detected markers"
marks=$(python3 -c 'import json,sys; print(" ".join("--mark %.3f,%.3f,%.3f" % tuple(c["centroid_lps_mm"]) for c in json.load(open(sys.argv[1]))["chosen"]))' "$out/fiducials.json")
i=0
for view in axial coronal sagittal; do
  centre=$(python3 -c 'import json,sys; c=json.load(open(sys.argv[1]))["chosen"][int(sys.argv[2])]; print("%.3f,%.3f,%.3f" % tuple(c["centroid_lps_mm"]))' "$out/fiducials.json" $i)
  label=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["chosen"][int(sys.argv[2])]["label"])' "$out/fiducials.json" $i)
  # shellcheck disable=SC2086
  "$plan" render "$out/phantom_ct" --view $view --lps "$centre" --window 2000 --level 300 --size 512 \
    --pixel-mm 0.16 $marks --out "$out/slice_${view}_${label}.png" > "$out/slice_${view}_${label}.json"
  i=$((i + 1))
done

echo "== needle deflection in soft tissue (extended bicycle model, seed 000)"
"$plan" deflection plot --k -0.0025 --ell 20 --out "$out/deflection_paths.png" | tee "$out/deflection_paths.json"
# An "observed" path: agar (Table I) every 2 mm, fitted back; the plain model fits it worse.
"$plan" deflection simulate --k -0.0025 --ell 20 --lambda1 0.49 --lambda2 0.22 --step 2 |
  python3 -c 'import json,sys; print("depth_mm,deflection_mm"); [print("%.6f,%.6f" % (r[1], r[2])) for r in json.load(sys.stdin)["path"][1:]]' \
  > "$out/agar_path.csv"
"$plan" deflection fit --k -0.0025 --ell 20 --in "$out/agar_path.csv" | tee "$out/deflection_fit.json"
"$plan" deflection plot --k -0.0025 --ell 20 --in "$out/agar_path.csv" --out "$out/deflection_fit.png" > /dev/null

echo "== the paper's IK simulation, closed form vs exact (writes figures)"
"$plan" study --robot "$robot" --out-dir "$out" > "$out/study.json"
echo
echo "Session folder: $out/"
ls -1 "$out"
echo "The server's session: $session/ (journal.jsonl, phantom_ct/, image_to_robot.tfm, fiducials and"
echo "targets .mrk.json, slices with overlays, summary.txt, report.md with the targeting errors of"
echo "the confirmation CTs: both passes, then a needle left in (verification/targeting.png,"
echo "seeds.mrk.json; tissues_fitted.yaml))."
echo "In 3D Slicer: load phantom_ct/ (DICOM), fiducials.mrk.json and image_to_robot.tfm, then put"
echo "feasible_volume.ply (robot frame) under the transform to see it in the CT. The anatomy:"
echo "structures.seg.nrrd (Slicer) or phantom_anatomy_rtstruct.dcm (SlicerRT, planning systems);"
echo "the targets proposed to fill the prostate: proposed_targets.mrk.json; where to mount the"
echo "robot: robot_placement.tfm (put feasible_volume.ply under it) and robot_placement.mrk.json."
echo "The seeds' dose: dose/ (in SlicerRT over phantom_ct/: structures_rtstruct.dcm, the RT Plans"
echo "and RT Doses; *_dose.nrrd as a scalar volume in Slicer; dvh.png, dvh.csv; report.md's Dose)."
echo "The slice PNGs (with their pixel -> LPS mapping in the matching .json) and IK_STUDY.md open"
echo "in any viewer."
