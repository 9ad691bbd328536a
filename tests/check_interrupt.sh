#!/bin/bash
# check_interrupt.sh render|bench PROGRAM DIR SIGNAL
# Sends SIGNAL (INT or TERM) to a program while it writes its output OUT in DIR, and checks that
# it dies of the signal and that OUT is as it was:
#   render  kdrt-render writing a large EXR, signalled once its temporary OUT.tmp-* holds data:
#           the temporary must be gone.
#   bench   kdrt-bench -o OUT, signalled once OUT.partial holds a row: OUT.partial must hold
#           whole rows, and kdrt-bench must say so.
set -u
set -m  # its own process group, so that SIGINT is not ignored as in a script's background job
kind=$1 program=$2 dir=$3 signal=$4
out=$dir/interrupted_${kind}_$signal.$([ "$kind" = render ] && echo exr || echo csv)
fail() { echo "FAIL: $*"; exit 1; }

rm -f "$out" "$out".*
printf 'the old file\n' > "$out.old"
cp "$out.old" "$out"
if [ "$kind" = render ]; then
  # Every ray misses (the sphere is behind the camera): the time goes to writing 16 Mpixels.
  printf 'camera: {position: [0, 0, 0], target: [0, 0, -1]}\nmaterials: [{name: white}]\nspheres: [{center: [0, 0, 10], radius: 1, material: white}]\n' > "$dir/interrupted.yaml"
  "$program" --scene "$dir/interrupted.yaml" --size 4096x4096 --exr-float -o "$out" 2> "$out.stderr" &
  # A temporary with data in it: kdrt-render's writability probe, named as its temporaries are,
  # is created empty and removed before the render, and signalling then tests nothing.
  ready() { [ -n "$(find "$dir" -maxdepth 1 -name "$(basename "$out").tmp-*" -size +0 2> /dev/null)" ]; }
else
  "$program" --size 64x64 --leaf-sizes 1,2,4 --repeat 1024 --reference-rays 16 -o "$out" 2> "$out.stderr" &
  ready() { [ -f "$out.partial" ] && [ "$(wc -l < "$out.partial")" -ge 2 ]; }
fi
pid=$!
for ((i = 0; i < 6000; ++i)); do  # 60 s at most
  ready && break
  kill -0 $pid 2> /dev/null || fail "$program ended before the moment to signal it"
  sleep 0.01
done
ready || fail "the moment to signal $program did not come in 60 s"
kill -s "$signal" $pid
wait $pid
status=$?
cat "$out.stderr"
[ $status -eq $((128 + $(kill -l "$signal"))) ] || fail "exit status $status, not death by SIG$signal"
cmp -s "$out" "$out.old" || fail "$out was changed"
if [ "$kind" = render ]; then
  ! compgen -G "$out.tmp-*" > /dev/null || fail "temporaries left: $(echo "$out".tmp-*)"
else
  grep -q "kdrt-bench: interrupted; the rows so far are in '$out.partial', and '$out' is as it was" "$out.stderr" ||
    fail "kdrt-bench did not say where its rows are"
  [ -z "$(tail -c 1 "$out.partial")" ] || fail "$out.partial ends in a partial line"
  columns=$(head -n 1 "$out.partial" | tr -cd ';' | wc -c)
  # Every column there; BuildThreads, fifth from last, never empty (Quality, Query and Start may
  # be).
  awk -F';' -v n=$((columns + 1)) 'NF != n || $(NF - 4) == "" { exit 1 }' "$out.partial" ||
    fail "$out.partial has a row cut short"
fi
echo "SIG$signal: $program died of it, $out as it was$([ "$kind" = bench ] && echo ", $(($(wc -l < "$out.partial") - 1)) row(s) in $out.partial")"
