#!/usr/bin/env bash
# Runs every fuzz target for SECONDS each on a working copy of its seed corpus and prints, per
# target, the executions and whether it found anything (crash, leak, timeout, out-of-memory, UB:
# the build aborts on UB). Exit status 1 when any target found something; the reproducers are
# in BUILD/fuzz-artifacts/<target>/.
#   fuzz/run.sh BUILD SECONDS [TARGET...]
set -uo pipefail
build=${1:?build folder}
seconds=${2:?seconds per target}
shift 2
root=$(cd "$(dirname "$0")/.." && pwd)
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  targets=(fuzz_nmea fuzz_nmea_stream fuzz_imu_csv fuzz_nav_csv fuzz_imu_datagram fuzz_gpsd fuzz_ubx fuzz_rig fuzz_scene
           fuzz_scenario fuzz_calib fuzz_model fuzz_codec fuzz_recording fuzz_euroc fuzz_source_uri
           fuzz_websocket fuzz_foxglove_ops fuzz_mcap)
fi

# Inputs of the length real files have; larger ones only slow the search down.
max_len() {
  case $1 in
    fuzz_source_uri) echo 512 ;;
    fuzz_model | fuzz_recording | fuzz_calib | fuzz_mcap) echo 16384 ;;
    *) echo 8192 ;;
  esac
}

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
found=0
printf '%-20s %12s  %s\n' target executions result
for t in "${targets[@]}"; do
  bin="$build/fuzz/$t"
  corpus="$build/fuzz-corpus/$t"
  artifacts="$build/fuzz-artifacts/$t/"
  log="$build/fuzz-logs/$t.log"
  mkdir -p "$corpus" "$artifacts" "$(dirname "$log")"
  # New inputs go to the working corpus; the committed seeds stay as they are.
  "$bin" -max_total_time="$seconds" -max_len="$(max_len "$t")" -timeout=10 -rss_limit_mb=2048 \
    -malloc_limit_mb=1024 -print_final_stats=1 -artifact_prefix="$artifacts" "$corpus" \
    "$root/tests/data/fuzz/$t" >"$log" 2>&1
  rc=$?
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  if [ -z "$execs" ]; then  # it stopped before the final stats: the last status line's count
    execs=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#')
  fi
  if [ $rc -eq 0 ]; then
    result="nothing found"
  else
    found=1
    what=$(grep -m1 -oE 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer|UndefinedBehaviorSanitizer): [a-z-]+|runtime error: .*|==[0-9]+== ERROR: .*' "$log" | head -1)
    result="FOUND (rc $rc): ${what:-see log}; log $log, reproducer in $artifacts"
  fi
  printf '%-20s %12s  %s\n' "$t" "${execs:-?}" "$result"
done
exit $found
