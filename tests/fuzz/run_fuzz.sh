#!/usr/bin/env bash
# Runs one fuzz target for SECONDS from its seed corpus (every seed, the regressions among
# them, runs first), new inputs into a scratch corpus. Exit status: the fuzzer's (a crash,
# leak, timeout or sanitizer report is non-zero; its input is left under ARTIFACTS). The
# random seed is fixed (FUZZ_SEED, default 1) so that a run repeats; longer runs vary it.
# usage: run_fuzz.sh FUZZER SEED_DIR WORK_DIR ARTIFACT_PREFIX SECONDS
set -uo pipefail
fuzzer=$1 seeds=$2 work=$3 artifacts=$4 seconds=$5
rm -rf "$work"
mkdir -p "$work" "$(dirname "$artifacts")"
log="$work.log"
"$fuzzer" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
  -seed="${FUZZ_SEED:-1}" -artifact_prefix="$artifacts" "$work" "$seeds" > "$log" 2>&1
rc=$?
# protobuf's complaints about the fuzzer's invalid UTF-8 are expected noise.
grep -v "libprotobuf ERROR" "$log" | grep -E "INITED|DONE|stat::|ERROR|SUMMARY|Test unit written|#[0-9]+ 0x" | head -40
echo "$(basename "$fuzzer"): exit $rc"
exit $rc
