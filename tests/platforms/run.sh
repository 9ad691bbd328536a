#!/usr/bin/env bash
# The platform checks, each a script of this folder: the stored answers (answers.txt) and the
# trees saved on x86-64 (answers.kdrt; answers.c says what is checked) on this machine's builds,
# the MSVC object code, mingw-w64 under wine, aarch64 under qemu-user and WebAssembly under node.
# Needs the cross toolchains: bash tools/setup.sh --platforms.
#   bash tests/platforms/run.sh [NAME...]    (default: all; e.g. run.sh native wasm)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
checks=("$@")
(( ${#checks[@]} )) || checks=(native msvc windows aarch64 wasm)
passed=0 failed=0 failures=()
for name in "${checks[@]}"; do
  if [[ ! -f $here/$name.sh ]]; then
    echo "run.sh: no check named '$name' (tests/platforms/$name.sh)" >&2; exit 2
  fi
  echo "=== platform: $name"
  start=$SECONDS
  if bash "$here/$name.sh"; then passed=$((passed + 1)); else failed=$((failed + 1)) failures+=("$name"); fi
  echo "=== platform: $name: $((SECONDS - start)) s"
done
(( failed == 0 )) || echo "run.sh: failed: ${failures[*]}"
echo "platforms: $passed passed, $failed failed"
(( failed == 0 ))
