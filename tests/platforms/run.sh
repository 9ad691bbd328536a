#!/usr/bin/env bash
# The platform checks, each a script of this folder: the stored answers (answers.txt) and the
# trees saved on x86-64 (answers.kdrt; answers.c says what is checked) on this machine's builds,
# the MSVC object code, mingw-w64 under wine, aarch64 under qemu-user and WebAssembly under node.
# Needs the cross toolchains: bash tools/setup.sh --platforms.
#   bash tests/platforms/run.sh [--jobs N] [NAME...]    (default: all; e.g. run.sh native wasm)
# --jobs N runs N checks at a time (default 1), each check's output printed whole when it ends.
# Each check keeps 2 cores busy most of its time, but not all of it (wine's and node's runs, the
# runs under qemu, the tails of its builds): 2 at a time, the longest (aarch64) beside the others
# one after another, fill those gaps.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
jobs=1
if [[ ${1-} == --jobs ]]; then
  if [[ ! ${2-} =~ ^[1-9][0-9]*$ ]]; then echo "run.sh: --jobs wants a whole number > 0, not '${2-}'" >&2; exit 2; fi
  jobs=$2
  shift 2
fi
checks=("$@")
(( ${#checks[@]} )) || checks=(aarch64 native msvc windows wasm)  # the longest first
for name in "${checks[@]}"; do
  if [[ ! -f $here/$name.sh ]]; then
    echo "run.sh: no check named '$name' (tests/platforms/$name.sh)" >&2; exit 2
  fi
done
passed=0 failed=0 failures=()

if (( jobs == 1 )); then
  for name in "${checks[@]}"; do
    echo "=== platform: $name"
    start=$SECONDS
    if bash "$here/$name.sh"; then passed=$((passed + 1)); else failed=$((failed + 1)) failures+=("$name"); fi
    echo "=== platform: $name: $((SECONDS - start)) s"
  done
else
  logs=$(mktemp -d)
  trap 'rm -rf "$logs"' EXIT
  # Each check in the background, its output and status to $logs; printed in the order they end.
  declare -A pid_of=()
  run_one() { # NAME
    local start=$SECONDS status=0
    bash "$here/$1.sh" >"$logs/$1.log" 2>&1 || status=$?
    echo "$status $((SECONDS - start))" >"$logs/$1.status.new"
    mv "$logs/$1.status.new" "$logs/$1.status"  # whole when it appears
  }
  report() { # NAME
    local status seconds
    read -r status seconds <"$logs/$1.status"
    echo "=== platform: $1"
    cat "$logs/$1.log"
    echo "=== platform: $1: $seconds s"
    if (( status == 0 )); then passed=$((passed + 1)); else failed=$((failed + 1)) failures+=("$1"); fi
  }
  # Waits for one check to end and reports it.
  reap() {
    local name
    wait -n || true
    for name in "${!pid_of[@]}"; do
      if [[ -f $logs/$name.status ]]; then report "$name"; unset "pid_of[$name]"; fi
    done
  }
  for name in "${checks[@]}"; do
    while (( ${#pid_of[@]} >= jobs )); do reap; done
    echo "=== platform: $name starts (at $SECONDS s)"
    run_one "$name" &
    pid_of[$name]=$!
  done
  while (( ${#pid_of[@]} > 0 )); do reap; done
fi
(( failed == 0 )) || echo "run.sh: failed: ${failures[*]}"
echo "platforms: $passed passed, $failed failed"
(( failed == 0 ))
