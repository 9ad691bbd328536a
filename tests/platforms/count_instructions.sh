#!/usr/bin/env bash
# What the NEON kernel costs against the scalar kernel on aarch64, in instructions executed per
# ray (qemu emulates, so its time says nothing). Not part of CI.
#   bash tests/platforms/count_instructions.sh [RAYS] [gcc|clang]     (default: 20000 gcc)
# kernel_speed.c, built for aarch64 at -O2, traces RAYS rays (nearest hit, watertight test) on its
# bumpy sphere of 49,152 triangles with one kernel; insn_count.c, a QEMU plugin, counts every
# guest instruction the run executes. Each kernel runs twice, with RAYS rays and with none (the
# mesh, the tree's build and the program around them), and the difference over RAYS is that
# kernel's instructions per ray: the walk, the triangle tests and kdrt_intersect's setup, plus the
# few dozen instructions kernel_speed takes to make a ray. Both runs' answers must match.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
rays=${1:-20000}
compiler=${2:-gcc}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
qemu=(qemu-aarch64 -L /usr/aarch64-linux-gnu -plugin "$work/insn_count.so" -d plugin)

cc -shared -fPIC -O2 -Wall -Wextra tests/platforms/insn_count.c -o "$work/insn_count.so"
case $compiler in
  gcc) target=(aarch64-linux-gnu-gcc) ;;
  clang) target=(clang --target=aarch64-linux-gnu) ;;
  *) echo "count_instructions.sh: compiler '$compiler': gcc or clang" >&2; exit 2 ;;
esac
"${target[@]}" -std=c99 -O2 -Iinclude tests/platforms/kernel_speed.c -o "$work/kernel_speed" -lm

count() { "${qemu[@]}" "$work/kernel_speed" "$1" "$2" 2>&1 | sed -n 's/^instructions //p'; }
answers() { qemu-aarch64 -L /usr/aarch64-linux-gnu "$work/kernel_speed" "$1" "$2" | sed -n 's/.*checksum \([0-9a-f]*\).*/\1/p'; }
declare -A per_ray
for kernel in simd scalar; do
  base=$(count 0 $kernel) total=$(count "$rays" $kernel)
  per_ray[$kernel]=$(( (total - base) / rays ))
  printf '%-6s kernel: %d instructions with %d rays, %d with none: %d per ray\n' \
    "$kernel" "$total" "$rays" "$base" "${per_ray[$kernel]}"
done
simd_answers=$(answers "$rays" simd) scalar_answers=$(answers "$rays" scalar)
if [[ $simd_answers != "$scalar_answers" ]]; then
  echo "count_instructions.sh: the kernels' answers differ (checksums $simd_answers, $scalar_answers)" >&2
  exit 1
fi
awk -v s="${per_ray[simd]}" -v c="${per_ray[scalar]}" -v cc="$compiler" \
  'BEGIN { printf "%s -O2: the NEON kernel executes %.2f times fewer instructions per ray than the scalar kernel (same answers)\n", cc, c / s }'
