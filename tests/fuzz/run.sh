#!/usr/bin/env bash
# Runs kdrt's libFuzzer targets (tests/fuzz) for a bounded time; see --help.
set -euo pipefail

ALL_TARGETS=(tree optics scene mesh scene_api scene_diff batch load queries)
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
build="build-fuzz" seconds=600 jobs=1 targets=()

usage() {
  cat <<USAGE
usage: bash tests/fuzz/run.sh [--build DIR] [--seconds N] [--jobs N] [TARGET...]

Fuzzes each TARGET (default: ${ALL_TARGETS[*]}) for N seconds (default 600), starting from
its seed corpus (tests/fuzz/corpus/TARGET; the scene target also from examples/render/scenes),
JOBS targets at a time (default 1). DIR is a build configured with Clang and -DKDRT_FUZZ=ON
(default build-fuzz); the targets are built there first:

  CC=clang CXX=clang++ cmake -S . -B build-fuzz -DKDRT_FUZZ=ON

Each input gets at most 10 s and 2 GB, and no single allocation may exceed 1 GB.
New inputs that reach new code go to DIR/fuzz/corpus/TARGET, kept between runs, so a longer
session carries on from the last one. A crash, a leak, undefined behaviour, a broken check, a
timeout or running out of memory stops that target: its report and the input (the file in
DIR/fuzz/findings/TARGET/, and in base64 when small) are printed with the command that
reproduces it, and the script exits 1. Each target's full log is DIR/fuzz/TARGET.log.

  --build DIR    the build folder (default build-fuzz)
  --seconds N    fuzzing time per target (default 600)
  --jobs N       targets fuzzed at the same time (default 1; each uses one core)
  --help         this text
USAGE
}

while [[ $# -gt 0 ]]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    --build) build=${2:?--build wants a folder}; shift 2 ;;
    --seconds) seconds=${2:?--seconds wants a number}; shift 2 ;;
    --jobs) jobs=${2:?--jobs wants a number}; shift 2 ;;
    -*) echo "run.sh: unknown option '$1'" >&2; usage >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
[[ ${#targets[@]} -gt 0 ]] || targets=("${ALL_TARGETS[@]}")
for n in "$seconds" "$jobs"; do
  if ! [[ $n =~ ^[1-9][0-9]*$ ]]; then echo "run.sh: --seconds and --jobs want a whole number > 0, not '$n'" >&2; exit 2; fi
done
for t in "${targets[@]}"; do
  if ! [[ " ${ALL_TARGETS[*]} " == *" $t "* ]]; then echo "run.sh: unknown target '$t' (${ALL_TARGETS[*]})" >&2; exit 2; fi
done
if [[ ! -f $build/CMakeCache.txt ]] || ! grep -q '^KDRT_FUZZ:BOOL=ON' "$build/CMakeCache.txt"; then
  echo "run.sh: $build is not a build with -DKDRT_FUZZ=ON; make one with:" >&2
  echo "  CC=clang CXX=clang++ cmake -S . -B $build -DKDRT_FUZZ=ON" >&2
  exit 2
fi
cmake --build "$build" -j2 --target "${targets[@]/#/kdrt_fuzz_}"
build=$(cd "$build" && pwd)

# Runs one target to its end; returns libFuzzer's status.
fuzz_one() {
  local t=$1 out="$build/fuzz"
  local seeds=("$here/corpus/$t")
  [[ $t == scene ]] && seeds+=("$here/../../examples/render/scenes")
  mkdir -p "$out/corpus/$t" "$out/findings/$t" "$out/tmp/$t"
  rm -f "$out/$t.status"
  # The scene and mesh targets write their files under TMPDIR: a crash cannot leave them in /tmp.
  TMPDIR="$out/tmp/$t" LSAN_OPTIONS="suppressions=$here/../sanitizer/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}" \
  "$build/tests/fuzz/kdrt_fuzz_$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024 \
    -print_final_stats=1 -artifact_prefix="$out/findings/$t/" "$out/corpus/$t" "${seeds[@]}" >"$out/$t.log" 2>&1
}

# What a target did, and for a finding the report, the input and how to reproduce it.
report() {
  local t=$1 status=$2 log="$build/fuzz/$t.log"
  local runs
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  if [[ $status -eq 0 ]]; then
    printf 'fuzz %s: %s inputs in %s s, no finding\n' "$t" "${runs:-?}" "$seconds"
    return 0
  fi
  printf '\nfuzz %s: FINDING (libFuzzer exit %s) after %s inputs; the report:\n' "$t" "$status" "${runs:-?}"
  # The report starts at the sanitizer's or libFuzzer's ==PID== line, or at our own check's line.
  awk '/^==[0-9]+==|^fuzz_[a-z]+: .*check failed|^ALARM|^(SUMMARY|MS): / {on = 1} on' "$log" | head -n 80
  local input
  input=$(sed -n 's/^.*Test unit written to //p' "$log" | tail -n 1)
  if [[ -n $input && -f $input ]]; then
    echo "the input: $input ($(wc -c <"$input") bytes)"
    if [[ $(wc -c <"$input") -le 4096 ]]; then
      echo "in base64 (decode with: base64 -d > input):"
      base64 -w 100 "$input"
    fi
    echo "reproduce: $build/tests/fuzz/kdrt_fuzz_$t $input"
  fi
  echo "the whole log: $log"
  return 1
}

failed=0 running=0
for t in "${targets[@]}"; do
  if [[ $running -ge $jobs ]]; then
    wait -n || true
    running=$((running - 1))
  fi
  (status=0; fuzz_one "$t" || status=$?; echo "$status" >"$build/fuzz/$t.status") &
  running=$((running + 1))
done
wait
rm -rf "$build/fuzz/tmp"
for t in "${targets[@]}"; do
  report "$t" "$(cat "$build/fuzz/$t.status")" || failed=1
done
exit $failed
