#!/usr/bin/env bash
# make tidy: clang-tidy (the checks of .clang-tidy) over every product .cpp that the build's
# compilation database compiles (not tests/; fuzz/ is built with clang in its own folder), JOBS
# files at a time, a line per file as each ends. Exits 1 when any file has an error: a function
# over 150 lines is one (.clang-tidy: readability-function-size is in WarningsAsErrors).
# Usage: scripts/tidy.sh [BUILD_DIR] [FILE...]   (JOBS from the environment, default: nproc)
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
shift || true
jobs=${JOBS:-$(nproc)}
db="$build/compile_commands.json"
[[ -f $db ]] || { echo "tidy: $db not found (configure first: make configure)" >&2; exit 2; }

# The product files in the database (or those given).
if (($# > 0)); then
  files=("$@")
else
  mapfile -t files < <(git ls-files '*.cpp' | grep -v '^tests/' | python3 -c '
import json, os, sys
db = {os.path.realpath(e["file"]) for e in json.load(open(sys.argv[1]))}
for f in sys.stdin.read().split():
    if os.path.realpath(f) in db: print(f)' "$db")
fi
total=${#files[@]}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
: >"$tmp/done"
echo "tidy: ${total} files, ${jobs} at a time"

# One file: its output printed whole once it ends (parallel runs do not interleave), with the
# count of files done so far.
one() {
  local f=$1 out rc=0
  out=$(clang-tidy -p "$build" --quiet "$f" 2>&1) || rc=$?
  # clang-tidy's "N warnings generated." lines say nothing the diagnostics do not.
  out=$(grep -v -E '^[0-9]+ warnings? (and [0-9]+ errors? )?generated\.$|^Suppressed [0-9]+ warnings' <<<"$out" || true)
  {
    flock 9
    echo "$f" >>"$tmp/done"
    local n
    n=$(wc -l <"$tmp/done")
    if ((rc != 0)); then
      echo "[$n/$total] $f: FAILED"
      echo "$f" >>"$tmp/failed"
    elif [[ -n $out ]]; then
      echo "[$n/$total] $f: warnings"
    else
      echo "[$n/$total] $f"
    fi
    [[ -n $out ]] && printf '%s\n' "$out"
  } 9>"$tmp/lock"
  return 0
}
export -f one
export build total tmp

printf '%s\0' "${files[@]}" | xargs -0 -P "$jobs" -n 1 bash -c 'one "$1"' _
if [[ -s $tmp/failed ]]; then
  echo "tidy: $(wc -l <"$tmp/failed") of ${total} files have errors:" >&2
  sed 's/^/  /' "$tmp/failed" >&2
  exit 1
fi
echo "tidy: clean (${total} files)"
