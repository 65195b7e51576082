#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan; the "fuzz" CMake preset) and runs each on its
# corpus for a while. Usage: tools/fuzz.sh [SECONDS_PER_TARGET=30] [TARGET...]
# Corpora start from tests/fuzz/seeds/<target> (plus, for DICOM, a phantom slice and pydicom's test
# files) and grow in build-fuzz/corpus/<target>; crashes land in build-fuzz/findings/<target>.
# Prints one line per target: runs, coverage, corpus size, result. Exit 1 on any finding.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-30}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_dicom fuzz_nrrd fuzz_metaimage fuzz_seg_nrrd fuzz_robot_config fuzz_journal
  fuzz_command fuzz_igtl)

cmake --preset fuzz >/dev/null
cmake --build build-fuzz -j "$(nproc)" --target fuzzers ignav-plan

root="$PWD/build-fuzz"
mkdir -p "$root/corpus" "$root/findings" "$root/logs"

seed_corpus() {  # target, corpus dir
  local name="${1#fuzz_}" dir="$2"
  mkdir -p "$dir"
  [ -d "tests/fuzz/seeds/$name" ] && cp -n tests/fuzz/seeds/"$name"/* "$dir"/ 2>/dev/null || true
  if [ "$name" = dicom ]; then
    # Real files, gathered here rather than copied into the repository: one slice of our own
    # phantom series and pydicom's edge cases (byte orders, implicit VR, no meta, truncation).
    if [ ! -e "$dir/phantom_slice.dcm" ]; then
      local tmp
      tmp="$(mktemp -d)"
      "$root/tools/ignav-plan/ignav-plan" phantom "$tmp/ph" --robot configs/robots/torabi2014.yaml \
        >/dev/null
      cp "$(find "$tmp/ph" -name '*.dcm' | sort | head -1)" "$dir/phantom_slice.dcm"
      rm -rf "$tmp"
    fi
    local pyd=/usr/lib/python3/dist-packages/pydicom/data/test_files
    for f in CT_small MR_small MR_small_bigendian MR_small_implicit MR_small_expb MR_truncated \
      no_meta ExplVR_BigEnd ExplVR_LitEndNoMeta rtdose_1frame liver_1frame badVR \
      empty_charset_LEI; do
      [ -e "$pyd/$f.dcm" ] && cp -n "$pyd/$f.dcm" "$dir/pydicom_$f.dcm"
    done
  fi
}

# Each target runs alone on its corpus, as many at once as there are cores (a fuzzer uses one):
# on two cores the fuzzing takes half as long.
lanes="$(nproc)"
fuzz_one() {  # target: runs it, leaves its line in logs/<target>.result
  local t="$1" corpus="$root/corpus/$1" dict="tests/fuzz/dicts/${1#fuzz_}.dict"
  local args=(-max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536
    -print_final_stats=1 -artifact_prefix="$root/findings/$t-")
  [ -f "$dict" ] && args+=(-dict="$dict")
  local log="$root/logs/$t.log" result=ok
  "$root/tests/fuzz/$t" "${args[@]}" "$corpus" >"$log" 2>&1 || result="FINDING (see $log)"
  local runs cov
  runs="$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo '?')"
  cov="$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo '?')"
  printf '%-18s %10s %8s %8s  %s\n' "$t" "$runs" "$cov" "$(ls "$corpus" | wc -l)" "$result" \
    >"$root/logs/$t.result"
}

for t in "${targets[@]}"; do
  seed_corpus "$t" "$root/corpus/$t"
  rm -f "$root/logs/$t.result"
  fuzz_one "$t" &
  while [ "$(jobs -rp | wc -l)" -ge "$lanes" ]; do wait -n || true; done
done
wait

status=0
printf '%-18s %10s %8s %8s  %s\n' target runs cov corpus result
for t in "${targets[@]}"; do
  if [ -f "$root/logs/$t.result" ]; then
    cat "$root/logs/$t.result"
    grep -q ' ok$' "$root/logs/$t.result" || status=1
  else
    printf '%-18s did not finish\n' "$t"
    status=1
  fi
done
exit "$status"
