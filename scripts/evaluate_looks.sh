#!/usr/bin/env bash
# scripts/evaluate_looks.sh SOURCE OUT [extra evaluate args]
#
# Issue 33 §3: `augrig evaluate` on one simulated flight three ways, the boom drawn in by augrig in
# the plain look and in the camera look, and physically in the simulated scene (--look physical),
# all three with the scenario's own boom (--boom scenario: the boom the physical frames show, so
# the masks and stereo classes are the same in all three). Then one table, per stereo class over
# every receiver pixel: the augmented pair's bad > 3 px rate for plain, camera and physical, and
# camera - physical, plain - physical in percentage points; the same for valid %.
#
#   SOURCE  a simulated flight, sim://SCENARIO[?every=K&bayer=RG...] (no boom= parameter)
#   OUT     OUT/plain, OUT/camera, OUT/physical (each `evaluate --out`, its log beside it as
#           OUT/LOOK.log) and OUT/looks.txt (the table, also printed)
#   extra   passed to every run, e.g. --frames 300 --every 3 --matcher m.yaml (not --look, --boom,
#           --out)
#
# The rates are the whole run's, recomputed exactly from each run's evaluation_sums.csv
# (bad3 / valid and valid / pixels summed over the frames, as the evaluation table does).
# The augrig binary: $AUGRIG, else build/augrig of this checkout.
set -euo pipefail

usage() {
  echo "usage: $0 SOURCE OUT [extra evaluate args]   (SOURCE: sim://SCENARIO[?...])" >&2
  exit 2
}
[ $# -ge 2 ] || usage
source_uri=$1
out=$2
shift 2
case "$source_uri" in
  sim://*) ;;
  *) echo "$0: SOURCE must be a simulated flight (sim://SCENARIO): only it has the physical boom" >&2; exit 2 ;;
esac
case "$source_uri" in
  *[?\&]boom=*) echo "$0: SOURCE has a boom= parameter: leave it out (the physical run adds boom=physical)" >&2; exit 2 ;;
esac
for a in "$@"; do
  case "$a" in
    --look | --look=* | --boom | --boom=* | --out | --out=*)
      echo "$0: $a is the script's to give (every run: --look LOOK --boom scenario --out OUT/LOOK)" >&2
      exit 2
      ;;
  esac
done
augrig=${AUGRIG:-$(cd "$(dirname "$0")/.." && pwd)/build/augrig}
[ -x "$augrig" ] || { echo "$0: no augrig binary at $augrig (build it, or set AUGRIG)" >&2; exit 2; }

mkdir -p "$out"
looks="plain camera physical"
for look in $looks; do
  echo "== $look: $augrig evaluate '$source_uri' --look $look --boom scenario --out $out/$look $*"
  start=$(date +%s)
  if ! "$augrig" evaluate "$source_uri" --look "$look" --boom scenario --out "$out/$look" --no-plot "$@" \
      >"$out/$look.log" 2>&1; then
    echo "$0: augrig evaluate --look $look failed; the end of $out/$look.log:" >&2
    tail -n 20 "$out/$look.log" >&2
    exit 1
  fi
  echo "   $(grep -m1 '^Evaluated ' "$out/$look.log" || true) [$(($(date +%s) - start)) s]"
done

# One awk program over the three evaluation_sums.csv files: per file and class, the sums of the
# augmented pair's pixels, valid and bad3 over every receiver pixel ("all"), and the plain run's
# raw pair (no boom) for reference.
awk -v looks="$looks" -v source="$source_uri" -v extra="$*" '
BEGIN {
  FS = ","
  nk = split("receiver both left_only right_only neither", key, " ")
  split("Receiver (all pixels)|Stereo: visible to both|Stereo: left only|Stereo: right only|Stereo: neither", name, "|")
  nl = split(looks, look, " ")
}
FNR == 1 {
  ++file
  frames[file] = 0
  for (i = 1; i <= NF; ++i) col[$i] = i
  for (k = 1; k <= nk; ++k) {
    for (f = 0; f < 3; ++f) {
      c = (f == 0 ? "pixels" : f == 1 ? "valid" : "bad3")
      if (!(("aug_all_" key[k] "_" c) in col) || !(("raw_all_" key[k] "_" c) in col)) {
        printf "%s: no column aug_all_%s_%s (not an evaluation_sums.csv?)\n", FILENAME, key[k], c > "/dev/stderr"
        bad = 1
        exit 1
      }
    }
  }
  next
}
{
  frames[file]++
  for (k = 1; k <= nk; ++k) {
    pixels[file, k] += $(col["aug_all_" key[k] "_pixels"])
    valid[file, k] += $(col["aug_all_" key[k] "_valid"])
    bad3[file, k] += $(col["aug_all_" key[k] "_bad3"])
    raw_valid[file, k] += $(col["raw_all_" key[k] "_valid"])
    raw_bad3[file, k] += $(col["raw_all_" key[k] "_bad3"])
  }
}
function pct(n, d) { return d > 0 ? 100.0 * n / d : "-" }
function cell(v, w) { return v == "-" ? sprintf("%" w "s", "-") : sprintf("%" w ".1f", v) }
function diff(a, b, w,   d) {
  if (a == "-" || b == "-") return sprintf("%" w "s", "-")
  d = sprintf("%.1f", a - b)
  if (d == "-0.0") d = "0.0"
  return sprintf("%" w "s", (d + 0 >= 0 ? "+" : "") d)
}
END {
  if (bad) exit 1
  if (file != nl) { printf "expected %d evaluation_sums.csv files, read %d\n", nl, file > "/dev/stderr"; exit 1 }
  printf "Three looks on %s%s\n", source, (extra == "" ? "" : " (" extra ")")
  printf "Frames evaluated: plain %d, camera %d, physical %d. Every receiver pixel, summed over the frames.\n", frames[1], frames[2], frames[3]
  printf "The augmented pair per look: plain and camera, the boom drawn in by augrig; physical, the\n"
  printf "simulator'\''s frames with the boom in the scene. All three with the scenario'\''s boom.\n"
  printf "Raw: the plain run'\''s raw pair (no boom). Differences in percentage points.\n"
  for (t = 0; t < 2; ++t) {
    printf "\n%s\n", t == 0 ? "Bad > 3 px (% of the valid pixels):" : "Valid (% of the pixels: the matcher gave a disparity):"
    printf "%-24s %9s | %6s | %6s %6s %8s | %9s %10s%s\n", "", "Pixels", "raw", "plain", "camera", "physical", "cam-phys", "plain-phys", (t == 0 ? " | |cam-phys| <= 2" : "")
    for (k = 1; k <= nk; ++k) {
      for (f = 1; f <= 3; ++f)
        v[f] = t == 0 ? pct(bad3[f, k], valid[f, k]) : pct(valid[f, k], pixels[f, k])
      r = t == 0 ? pct(raw_bad3[1, k], raw_valid[1, k]) : pct(raw_valid[1, k], pixels[1, k])
      verdict = ""
      if (t == 0 && v[2] != "-" && v[3] != "-") {
        d = v[2] - v[3]
        verdict = (d <= 2 && d >= -2) ? "yes" : "no"
      }
      printf "%-24s %9d | %s | %s %s %s | %s %s%s\n", name[k], pixels[3, k], cell(r, 6), cell(v[1], 6), cell(v[2], 6), cell(v[3], 8), diff(v[2], v[3], 9), diff(v[1], v[3], 10), (t == 0 ? " | " verdict : "")
    }
  }
  for (k = 1; k <= nk; ++k)
    if (pixels[1, k] != pixels[3, k] || pixels[2, k] != pixels[3, k])
      printf "\nNOTE: the class %s has %d / %d / %d pixels in the three runs: not the same boom or frames.\n", key[k], pixels[1, k], pixels[2, k], pixels[3, k]
}
' "$out/plain/evaluation_sums.csv" "$out/camera/evaluation_sums.csv" "$out/physical/evaluation_sums.csv" \
  >"$out/looks.txt"
echo
cat "$out/looks.txt"
echo
echo "Wrote $out/looks.txt"
