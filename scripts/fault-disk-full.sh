#!/usr/bin/env bash
# Disk full during `augrig run --record`, as the independent fault runs did it: a 20 MB tmpfs, the
# simulated flight as fast as it goes, 12 s. Repeats RUNS times and checks that every recording
# was closed (summary.status written) with the drop ledger the terminal printed, and that `augrig
# check` reads it clean. Needs root (mount). Usage: scripts/fault-disk-full.sh [RUNS] [BUILD_DIR]
set -euo pipefail
runs=${1:-17}
build=${2:-build}
augrig="$(cd "$build" && pwd)/augrig"
mnt=$(mktemp -d /tmp/augrig-disk-full.XXXXXX)
trap 'umount "$mnt" 2>/dev/null || true; rmdir "$mnt"' EXIT
closed=0 by_checkpoint=0 true_ledger=0 check_ok=0
for i in $(seq 1 "$runs"); do
  mount -t tmpfs -o size=20m tmpfs "$mnt"
  out=$("$augrig" run --source 'sim://demo?every=3&rate=0' --duration 12 --headless --status-every 0 \
    --record "$mnt/rec" 2>&1 || true)
  status=$(sqlite3 "$mnt/rec/recording.sqlite" "SELECT value FROM meta WHERE key='summary.status'" 2>/dev/null || true)
  rec_drops=$(sqlite3 "$mnt/rec/recording.sqlite" "SELECT value FROM meta WHERE key='summary.drops.recorder'" 2>/dev/null || true)
  term_drops=$(sed -n 's/.*(\([0-9]*\) dropped by the recorder).*/\1/p' <<<"$out" | tail -1)
  kind=transaction
  [[ "$status" == *checkpoint* ]] && kind=checkpoint && by_checkpoint=$((by_checkpoint + 1))
  [[ -n "$status" ]] && closed=$((closed + 1))
  [[ -n "$rec_drops" && "$rec_drops" == "$term_drops" ]] && true_ledger=$((true_ledger + 1))
  "$augrig" check "$mnt/rec" > /dev/null 2>&1 && check_ok=$((check_ok + 1))
  printf 'run %2d: stopped in a %-11s closed %-3s recorder drops: terminal %s, recording %s\n' \
    "$i" "$kind," "$([[ -n "$status" ]] && echo yes || echo NO)" "${term_drops:-?}" "${rec_drops:-none}"
  umount "$mnt"
done
echo "$runs runs: $closed closed, $true_ledger with the terminal's ledger, $check_ok check clean; $by_checkpoint stopped by a WAL checkpoint"
[[ $closed -eq $runs && $true_ledger -eq $runs && $check_ok -eq $runs ]]
