#!/usr/bin/env bash
# Loading a 512x512xN CT series, every reader as a whole process, interleaved in one run (round r
# runs each reader once, in turn) on the same files with a warm page cache:
#   read-loop   read(2) of every file into one 1 MiB buffer, nothing decoded: the I/O limit
#   read-into   the same into one fresh buffer as large as the files (huge pages, as ignav's
#               voxels): the limit for a process that ends up holding the volume
#   dcm2niix    Debian's dcm2niix to an uncompressed NIfTI
#   ignav       ignav's reader alone (build/tools/bench/bench_volume_load SERIES 1)
#   ignav-plan  the CLI's volume-info (also computes the HU range)
# Prints each reader's median wall time and peak RSS, and the median of the paired ratios
# ignav / anchor (< 1: ignav is faster). Then ignav's warm in-process median, for reference: a
# whole process also pays its start (dynamic linking, DCMTK's data dictionary), the server once.
# Last, the reader on one thread and on two, next to two single-threaded processes at once.
# Each run starts after a `sync`, so that nothing is written back during the next.
# Usage (after tools/build.sh):
#   tools/bench/bench_volume_load.sh [runs=5] [uncompressed|jpeg-ls|jpeg-lossless] [slices=300]
set -euo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-5}
encoding=${2:-uncompressed}
slices=${3:-300}
plan=build/tools/ignav-plan/ignav-plan
reader=build/tools/bench/bench_volume_load
work=$(mktemp -d /tmp/ignav_bench.XXXXXX)
trap 'rm -rf "$work"' EXIT
series="$work/series"
"$plan" phantom "$series" --dims "512,512,$slices" --noise-hu 10 >/dev/null
case "$encoding" in
  uncompressed) ;;
  jpeg-ls | jpeg-lossless)
    # DCMTK's own encoders, file by file (JPEG lossless: process 14, selection value 1).
    tool=(dcmcjpls)
    [ "$encoding" = jpeg-lossless ] && tool=(dcmcjpeg +e1)
    mkdir "$work/encoded"
    for f in "$series"/*; do "${tool[@]}" "$f" "$work/encoded/$(basename "$f")"; done
    rm -rf "$series"
    mv "$work/encoded" "$series"
    ;;
  *) echo "encoding '$encoding' is not uncompressed, jpeg-ls or jpeg-lossless" >&2; exit 2 ;;
esac
bytes=$(du -sb "$series" | cut -f1)
voxel_bytes=$((512 * 512 * slices * 2))
cat "$series"/* >/dev/null  # warm the page cache

readers=(read-loop read-into dcm2niix ignav ignav-plan)
command_of() {
  case "$1" in
    read-loop) echo "$reader --read-loop $series" ;;
    read-into) echo "$reader --read-into $series" ;;
    dcm2niix) echo "dcm2niix -z n -o $work/nii -f out $series" ;;
    ignav) echo "$reader $series 1" ;;
    ignav-plan) echo "$plan volume-info $series" ;;
  esac
}
mkdir -p "$work/nii"
for name in "${readers[@]}"; do : >"$work/$name.secs"; : >"$work/$name.rss"; done
for _ in $(seq "$runs"); do
  for name in "${readers[@]}"; do
    read -ra cmd <<<"$(command_of "$name")"
    sync
    # Wall time to the microsecond around the process (time(1)'s %e has 10 ms steps); RSS from it.
    t0=$EPOCHREALTIME
    if ! /usr/bin/time -f "%M" -o "$work/t" "${cmd[@]}" >"$work/out" 2>&1; then
      # e.g. Debian's dcm2niix, built without CharLS, cannot read JPEG-LS: said, not timed
      echo "$name cannot read this series: $(grep -m1 -i -E 'unsupported|error' "$work/out")"
      kept=()
      for r in "${readers[@]}"; do [ "$r" = "$name" ] || kept+=("$r"); done
      readers=("${kept[@]}")
      continue
    fi
    t1=$EPOCHREALTIME
    secs=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.4f", b - a }')
    read -r rss <"$work/t"
    # dcm2niix's NIfTI is deleted at once: 157 MB of page cache would otherwise hold memory
    # that the next process gets cold (on this VM, zeroing never-touched pages costs 2-3x more).
    rm -f "$work/nii/"*
    echo "$secs" >>"$work/$name.secs"
    echo "$rss" >>"$work/$name.rss"
  done
done

median() { sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'; }
echo "series: $slices files ($encoding), $((bytes / 1000000)) MB on disk," \
  "voxels $((voxel_bytes / 1000000)) MB; $runs interleaved rounds of whole processes"
for name in "${readers[@]}"; do
  s=$(median <"$work/$name.secs")
  r=$(median <"$work/$name.rss")
  ratio=""
  if [ "$name" != ignav ]; then
    ratio=$(paste "$work/ignav.secs" "$work/$name.secs" | awk '{print $1 / $2}' | median)
    ratio=$(printf "ignav / this: %.2f" "$ratio")
  fi
  awk -v n="$name" -v s="$s" -v b="$bytes" -v r="$r" -v v="$voxel_bytes" -v q="$ratio" 'BEGIN {
    printf "%-10s median %6.4f s  %7.0f MB/s  peak RSS %5.0f MB (%.2f x voxel bytes)  %s\n",
           n, s, b / s / 1e6, r / 1024, r * 1024 / v, q }'
done
echo "for reference, ignav's reader in one process, warm, $runs loads:"
"$reader" "$series" "$runs"
# Threads: what two cores give this decoder, against what the machine gives two independent
# processes (each its own single-threaded reader): whole processes of $runs loads, three rounds.
echo "threads ($runs loads per process; scaling = one thread's time / the other's, per round):"
for _ in 1 2 3; do
  t0=$EPOCHREALTIME; "$reader" "$series" "$runs" 1 >/dev/null
  t1=$EPOCHREALTIME; "$reader" "$series" "$runs" 1 >/dev/null & "$reader" "$series" "$runs" 1 >/dev/null; wait
  t2=$EPOCHREALTIME; "$reader" "$series" "$runs" 2 >/dev/null
  t3=$EPOCHREALTIME
  awk -v a="$t0" -v b="$t1" -v c="$t2" -v d="$t3" 'BEGIN {
    printf "  1 thread %.2f s; 2 threads %.2f s: %.2fx | two 1-thread processes at once %.2f s: the machine gives %.2fx\n",
           b - a, d - c, (b - a) / (d - c), c - b, 2 * (b - a) / (c - b) }'
done
