#!/usr/bin/env bash
# check-identical.sh: the outputs a change must leave byte for byte as they were (issue 34: the
# elements' refactoring), hashed into a manifest. Run it on the tree before and after the change
# and compare the two manifests:
#   scripts/check-identical.sh [BUILD_DIR] > before.txt     (BUILD_DIR default: build)
#   ... change, rebuild ...
#   scripts/check-identical.sh [BUILD_DIR] > after.txt
#   scripts/check-identical.sh --compare before.txt after.txt   (exit 1 and the lines that differ)
# What it hashes, each where the output is deterministic:
#   - the demo's stats.csv and the frames it writes (`augrig demo`);
#   - a short simulated run's recording (`augrig run --record`, no live nav): every column of every
#     frame row but the host clock's, and the blobs (raw, augmented, masks, depth);
#   - that recording replayed and re-recorded (`augrig replay --record --out`): the new recording's
#     frames the same way, and the replay's stats.csv;
#   - its MCAP export (the whole file) and its EuRoC export (every file but the gnuplot picture).
# The ledger's frames pending at the stop (a finite source's read-ahead: thread timing) and
# wall-clock times (recording metadata, the host clock's columns, events stamped on it) are left
# out, and set to the frames' own times in the recording the exports read. Progress goes to
# stderr; the manifest ("NAME SHA256" lines, sorted) to stdout.
set -euo pipefail

if [[ "${1:-}" == "--compare" ]]; then
  [[ $# -eq 3 ]] || { echo "usage: $0 --compare BEFORE AFTER" >&2; exit 2; }
  for f in "$2" "$3"; do [[ -s "$f" ]] || { echo "check-identical: $f: missing or empty manifest" >&2; exit 2; }; done
  if diff -u "$2" "$3"; then
    echo "check-identical: identical ($(wc -l < "$2") outputs)" >&2
    exit 0
  fi
  echo "check-identical: the outputs above differ" >&2
  exit 1
fi

BUILD="${1:-build}"
AUGRIG="$(cd "$BUILD" && pwd)/augrig"
[[ -x "$AUGRIG" ]] || { echo "check-identical: $AUGRIG: not built (make build)" >&2; exit 2; }
WORK="$(mktemp -d /tmp/check-identical.XXXXXX)"
trap 'rm -rf "$WORK"' EXIT
cd "$WORK"

step() { echo "check-identical: $*" >&2; }
# Runs augrig, its output in WORK/LOG; on failure shows the log's end and stops.
run() {
  local log="$1"; shift
  if ! "$AUGRIG" "$@" > "$log" 2>&1; then
    echo "check-identical: augrig $* failed:" >&2
    tail -20 "$log" >&2
    exit 1
  fi
}
# "NAME SHA256" for each file under DIR (relative names prefixed with LABEL), skipping EXCLUDE.
hash_tree() {
  local label="$1" dir="$2" exclude="${3:-^$}"
  (cd "$dir" && find . -type f | sed 's|^\./||' | grep -v -E "$exclude" | LC_ALL=C sort |
    while read -r f; do echo "$label/$f $(sha256sum "$f" | cut -d' ' -f1)"; done)
}
# "LABEL SHA256" of a recording's frames: each row's columns but the host clock's, blobs included,
# in row order; and the same of its other tables (depth, nav inputs, drops, events, look updates).
hash_recording() {
  python3 - "$1" "$2" <<'EOF'
import hashlib, sqlite3, sys
label, path = sys.argv[1], sys.argv[2] + "/recording.sqlite"
db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
def digest(table, order):
    cols = [r[1] for r in db.execute(f"PRAGMA table_info({table})") if "host" not in r[1]]
    h, n = hashlib.sha256(), 0
    for row in db.execute(f"SELECT {', '.join(cols)} FROM {table} ORDER BY {order}"):
        # What a finite source had read ahead when the run stopped depends on its threads' timing.
        if table == "drops" and row[cols.index("reason")].startswith("pending"):
            continue
        if table == "events" and row[cols.index("clock")] == "host_monotonic":
            row = tuple(None if c == "t_ns" else v for c, v in zip(cols, row))
        h.update(repr(row).encode()); n += 1
    return h.hexdigest(), n
tables = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
for table in ("frames", "depth", "nav_input", "drops", "events", "look"):
    if table in tables:
        d, n = digest(table, "rowid")
        print(f"{label}.{table}[{n}] {d}")
EOF
}

step "demo (the built-in flight, the main job)"
run demo.log demo --out demo
hash_tree demo demo

step "a short simulated run, recorded"
run rec.log run --source 'sim://demo?every=30&rate=0' --frames 12 --headless --status-every 0 --record rec
hash_recording run.recording rec

step "its replay, re-recorded"
run replay.log replay rec --fast --headless --record rec2 --out replay
hash_recording replay.recording rec2
hash_tree replay replay

# The exports' input without the run's wall-clock and thread timing: host times become the
# frames' own, the read-ahead pending at the stop is left out, so that the exports of two runs
# are comparable byte for byte.
python3 - rec <<'PY'
import sqlite3, sys
db = sqlite3.connect(sys.argv[1] + "/recording.sqlite")
for side in ("left", "right"):
    db.execute(f"UPDATE frames SET {side}_t_host_ns = {side}_t_ns")
db.execute("UPDATE events SET t_ns = (SELECT MIN(left_t_ns) FROM frames) + id WHERE clock = 'host_monotonic'")
db.execute("UPDATE meta SET value = '0' WHERE key LIKE '%utc%' OR key LIKE '%host%'")
# The read-ahead pending at the stop (thread timing), in the ledger and the summary.
db.execute("DELETE FROM drops WHERE reason LIKE 'pending%'")
db.execute("UPDATE meta SET value = '0' WHERE key = 'summary.drops.processing'")
db.commit()
PY

step "MCAP export"
run mcap.log export rec --format mcap rec.mcap
echo "export.mcap $(sha256sum rec.mcap | cut -d' ' -f1)"

step "EuRoC export"
run euroc.log export rec --format euroc euroc --no-plot
hash_tree export.euroc euroc
step "done"
