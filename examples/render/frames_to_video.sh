#!/usr/bin/env bash
# Turns kdrt-render's numbered frames (--animate ... --frames N) into a video with ffmpeg.
set -euo pipefail

usage() {
  cat <<USAGE
usage: bash examples/render/frames_to_video.sh FRAMES OUT.mp4 [--fps N]

FRAMES names the frames as kdrt-render was told to write them: the -o path (anim.png: frames
anim-0000.png, anim-0001.png, ...) or that path without its extension (anim). The frames are
numbered from 0000 without gaps; PNG or EXR (EXR is linear and is shown through the sRGB curve).
OUT is written as H.264 (yuv420p, plays everywhere) when it ends in .mp4, .mkv or .mov, else in
ffmpeg's choice for its extension; it is written to a temporary file first, so a failed run
leaves no half video behind.

  --fps N   frames per second, default 30 (180 frames: a 6 s video)
  --help    this text

Needs ffmpeg (optional for kdrt, not installed by tools/setup.sh: apt-get install ffmpeg).
The environment variable FFMPEG names another ffmpeg binary.

Example: kdrt-render --preset PHASE_4_REFRACTION --animate GLASS_IOR=1.0:2.0 --frames 180 -o ior.png
         bash examples/render/frames_to_video.sh ior.png ior.mp4
USAGE
}

die() { echo "frames_to_video: $*" >&2; exit 1; }

fps=30
args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    --fps)
      [[ $# -ge 2 ]] || die "--fps wants a number of frames per second"
      fps=$2; shift 2 ;;
    --fps=*) fps=${1#--fps=}; shift ;;
    -*) echo "frames_to_video: unknown option '$1'" >&2; usage >&2; exit 2 ;;
    *) args+=("$1"); shift ;;
  esac
done
if [[ ${#args[@]} -ne 2 ]]; then
  usage >&2
  exit 2
fi
frames=${args[0]}
out=${args[1]}
# A positive rate, whole or decimal (29.97).
if ! [[ $fps =~ ^[0-9]+(\.[0-9]+)?$ ]] || [[ $fps =~ ^0+(\.0+)?$ ]]; then
  die "--fps wants a positive number, got '$fps'"
fi

ffmpeg=${FFMPEG:-ffmpeg}
if ! command -v "$ffmpeg" >/dev/null 2>&1; then
  die "ffmpeg not found ('$ffmpeg'): install it (apt-get install ffmpeg) or set FFMPEG to its path"
fi

# The frames' prefix and extension: anim.png -> anim + png; anim -> whichever of png, exr exists.
case "$frames" in
  *.png|*.PNG|*.exr|*.EXR) prefix=${frames%.*}; ext=${frames##*.} ;;
  *)
    prefix=$frames; ext=
    for e in png exr; do
      if [[ -f "$prefix-0000.$e" ]]; then ext=$e; break; fi
    done
    [[ -n $ext ]] || die "no first frame '$prefix-0000.png' or '$prefix-0000.exr'"
    ;;
esac
[[ -f "$prefix-0000.$ext" ]] || die "no first frame '$prefix-0000.$ext'"

# ffmpeg stops at the first missing number: count the run from 0000 and refuse a gap, which
# would otherwise cut the video short without a word.
count=0
while [[ -f $(printf '%s-%04d.%s' "$prefix" "$count" "$ext") ]]; do
  count=$((count + 1))
done
shopt -s nullglob
numbered=("$prefix"-[0-9][0-9][0-9][0-9]."$ext")
shopt -u nullglob
if [[ ${#numbered[@]} -ne $count ]]; then
  die "frame $(printf '%s-%04d.%s' "$prefix" "$count" "$ext") is missing (${#numbered[@]} numbered frames are there): ffmpeg would stop at it"
fi

out_dir=$(dirname -- "$out")
[[ -d $out_dir ]] || die "the folder of '$out' does not exist"
out_name=$(basename -- "$out")
out_ext=${out_name##*.}
[[ $out_ext != "$out_name" ]] || die "'$out' has no extension to choose the format (use .mp4)"

input_options=()
[[ ${ext,,} == exr ]] && input_options=(-apply_trc iec61966_2_1)  # linear EXR to sRGB
codec_options=()
case "${out_ext,,}" in
  mp4|mkv|mov) codec_options=(-c:v libx264 -pix_fmt yuv420p -crf 18) ;;
esac

tmp="$out_dir/.${out_name%.*}.partial.$$.$out_ext"
trap 'rm -f -- "$tmp"' EXIT
# A % in the prefix would be read as part of ffmpeg's pattern.
pattern="${prefix//%/%%}-%04d.$ext"
# yuv420p needs even sides: pad an odd width or height by one pixel.
if ! "$ffmpeg" -hide_banner -loglevel error -nostdin -y -framerate "$fps" -start_number 0 \
    "${input_options[@]}" -i "$pattern" -frames:v "$count" \
    -vf 'pad=ceil(iw/2)*2:ceil(ih/2)*2' "${codec_options[@]}" "$tmp"; then
  die "ffmpeg failed on '$pattern' (its message is above)"
fi
mv -f -- "$tmp" "$out"
trap - EXIT
echo "frames_to_video: wrote $out ($count frames at $fps fps)"
