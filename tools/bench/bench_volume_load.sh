#!/usr/bin/env bash
# Loading a 512x512x300 CT series: ignav vs dcm2niix vs cat (the page-cache limit), same files,
# same run, warm cache. Prints the median of N runs in MB/s and the peak RSS of each reader.
# Usage: tools/bench/bench_volume_load.sh [runs=5]   (after tools/build.sh)
set -euo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-5}
plan=build/tools/ignav-plan/ignav-plan
work=$(mktemp -d /tmp/ignav_bench.XXXXXX)
trap 'rm -rf "$work"' EXIT
series="$work/series"
"$plan" phantom "$series" --dims 512,512,300 --noise-hu 10 >/dev/null
bytes=$(du -sb "$series" | cut -f1)
voxel_bytes=$((512 * 512 * 300 * 2))
cat "$series"/* >/dev/null  # warm the page cache

median() { sort -n | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'; }
# time_one CMD...: wall seconds and peak RSS (kB) of one run
time_one() { /usr/bin/time -f "%e %M" -o "$work/t" "$@" >/dev/null 2>&1; cat "$work/t"; }

report() {  # name, then the command
  local name=$1; shift
  : >"$work/secs"; : >"$work/rss"
  for _ in $(seq "$runs"); do
    read -r secs rss < <(time_one "$@")
    echo "$secs" >>"$work/secs"; echo "$rss" >>"$work/rss"
  done
  local s r
  s=$(median <"$work/secs"); r=$(median <"$work/rss")
  awk -v n="$name" -v s="$s" -v b="$bytes" -v r="$r" -v v="$voxel_bytes" 'BEGIN {
    printf "%-10s median %6.3f s  %7.0f MB/s  peak RSS %5.0f MB (%.2f x voxel bytes)\n",
           n, s, b / s / 1e6, r / 1024, r * 1024 / v }'
}

echo "series: 300 files, $((bytes / 1000000)) MB, voxels $((voxel_bytes / 1000000)) MB; $runs runs each"
report cat sh -c "cat '$series'/* > /dev/null"
mkdir -p "$work/nii"
report dcm2niix dcm2niix -z n -o "$work/nii" -f out "$series"
# ignav's reader alone, in a binary that links nothing else (ignav-plan also loads PCL/VTK)
build/tools/bench/bench_volume_load "$series" "$runs"
report ignav-plan "$plan" volume-info "$series"
