#!/usr/bin/env bash
# rangexctl end to end through its command line: a small recording is simulated,
# extracted, processed and evaluated; bad input must fail with exit code 1 and a message
# that names the problem.
set -u
ctl="$1"
source "$(dirname "$0")/script_checks.sh"
expect_error() {  # expect_error NAME PATTERN COMMAND...
  local name=$1 pattern=$2; shift 2
  local out rc
  out=$("$@" 2>&1); rc=$?
  if [ $rc -eq 1 ] && grep -q -- "$pattern" <<<"$out"; then echo "ok   $name"
  else echo "FAIL $name (exit $rc): $out"; fails=$((fails + 1)); fi
}

"$ctl" simulate --lanes 1 --fillets 1 --seed 5 --out "$work/rec" >/dev/null || { echo "FAIL simulate"; exit 1; }
check "recording.yaml written" test -f "$work/rec/recording.yaml"
check "truth written" test -f "$work/rec/lane0/truth/fragments.csv"

"$ctl" extract "$work/rec" --lane 0 --camera 1 --method gaussian3 --out "$work/peaks.csv" || fails=$((fails + 1))
check "extract header" grep -qx "frame,column,row" "$work/peaks.csv"
lines=$(awk -F'"' '/^lines:/{print}' "$work/rec/recording.yaml" | awk '{print $2}')
check "extract one row per column" test "$(($(wc -l <"$work/peaks.csv") - 1))" -eq "$((lines * 640))"
check "extract has empty rows where no stripe" grep -q ",$" "$work/peaks.csv"

"$ctl" process "$work/rec" --out "$work/out" >/dev/null || fails=$((fails + 1))
check "thickness png" test -s "$work/out/lane0/thickness.png"
check "summary json" grep -q '"valid_thickness_fraction"' "$work/out/summary.json"
# The recording's name goes into summary.json as a JSON string, whatever it holds.
odd="$work/rec \"quoted\" back\\slash"
ln -s "$work/rec" "$odd"
"$ctl" process "$odd" --out "$work/out_odd" --images none >/dev/null 2>&1 || fails=$((fails + 1))
check "summary json names a recording whose name holds quotes and a backslash" python3 -c \
  "import json,sys; sys.exit(0 if json.load(open(sys.argv[1]))['recording'] == sys.argv[2] else 1)" \
  "$work/out_odd/summary.json" "$odd"
# A path need not be UTF-8: what is not is written as U+FFFD, and the file is still JSON.
bad="$work/rec_$(printf '\377')_latin"
ln -s "$work/rec" "$bad"
"$ctl" process "$bad" --out "$work/out_bad" --images none >/dev/null 2>&1 || fails=$((fails + 1))
check "summary json names a recording whose name is not UTF-8" python3 -c \
  "import json,sys; sys.exit(0 if json.load(open(sys.argv[1]))['recording'].endswith('rec_\ufffd_latin') else 1)" \
  "$work/out_bad/summary.json"
json=$("$ctl" eval "$work/rec" "$work/out" --json)
mae=$(sed -E 's/.*"thickness_mm": \{[^}]*"mean_abs": ([0-9.e+-]+).*/\1/' <<<"$json")
check "eval thickness mean |error| <= 0.3 mm (got $mae)" awk -v m="$mae" 'BEGIN{exit !(m <= 0.3)}'

check "fillets table" grep -q "^lane,fillet,first_line" "$work/out/lane0/fillets.csv"
check "fillets json" grep -q '"decision"' "$work/out/lane0/fillets.json"
check "fillet images" test -s "$(ls -d "$work"/out/lane0/fillet_*/ | head -1)overlay.png"
"$ctl" eval "$work/rec" "$work/out" >"$work/eval.txt" || fails=$((fails + 1))
check "eval prints recall" grep -q "recall, calcified fragments >= 2 mm" "$work/eval.txt"

# A simulated plant processed in memory, evaluated from its own truth.
"$ctl" process --simulate --lanes 1 --fillets 3 --seed 4 --out "$work/plant" --images none >"$work/plant.txt" \
  || fails=$((fails + 1))
check "simulated plant prints the baseline" grep -q "X-ray only" "$work/plant.txt"
# ... and with a calibration of its own (no recording to name).
printf 'laser_plane: {normal: [0, 1, 0], offset_mm: 0.0}\n' >"$work/simcal.yaml"
"$ctl" process --simulate --calibration "$work/simcal.yaml" --lanes 1 --fillets 1 --seed 4 \
  --out "$work/plant_cal" --images none >"$work/plant_cal.txt" || fails=$((fails + 1))
check "simulated plant with a calibration" grep -q "simulating with .*simcal.yaml" "$work/plant_cal.txt"
"$ctl" eval "$work/plant" --json >"$work/plant.json" || fails=$((fails + 1))
check "eval of a simulated run" grep -q '"xray_only"' "$work/plant.json"

# The robust fit from the command line reproduces statsmodels' reference.
fit=$("$ctl" fit "$(dirname "$0")/data/rlm/outliers20.csv" --json)
check "fit json" grep -q '"beta0": 8.1023' <<<"$fit"
# The parabola of a hardened beam, as statsmodels fits it (reference_quadratic.csv).
fit2=$("$ctl" fit "$(dirname "$0")/data/rlm/hardened.csv" --degree 2 --json)
check "parabola json" grep -q '"beta2": 0.00016367' <<<"$fit2"
expect_error "bad lane list" "--lanes takes numbers from 1 to 16 separated by commas (got '4,x')" "$ctl" bench-server --lanes 4,x
expect_error "bench lines" "--lines must be >= 1 (got 0)" "$ctl" bench-server --lines 0
expect_error "bad degree" "--degree must be 1 (a line) or 2" "$ctl" fit "$(dirname "$0")/data/rlm/hardened.csv" --degree 3
printf 'T,lnI\n1,2\n3,x\n' >"$work/bad.csv"
expect_error "bad csv" "bad.csv:3: column 2 ('lnI') is not a finite number" "$ctl" fit "$work/bad.csv"

# The server: rangexd on a free loopback port, fed over gRPC, queried, stopped gracefully.
srv="$(dirname "$ctl")/../server/daemon/rangexd"
start_rangexd() {  # start_rangexd LOG: rangexd on the test's store; sets pid and addr
  "$srv" --listen 127.0.0.1:0 --http 127.0.0.1:0 --data "$work/data" >"$1" 2>&1 &
  pid=$!
  for _ in $(seq 600); do grep -q "listening on" "$1" && break; kill -0 $pid 2>/dev/null || break; sleep 0.1; done
  addr=$(sed -nE 's/.*listening on ([0-9.]+:[0-9]+).*/\1/p' "$1")
}
start_rangexd "$work/rangexd.log"
check "rangexd listens on loopback ($addr)" grep -q "^127.0.0.1:" <<<"$addr"
"$ctl" record start --server "$addr" --lanes 0 --minutes 5 --name cli-shift >/dev/null || fails=$((fails + 1))
"$ctl" feed --server "$addr" --simulate --lanes 2 --fillets 1 --seed 3 >"$work/feed.txt" || fails=$((fails + 1))
check "feed accepted every line" grep -q ", 0 refused" "$work/feed.txt"
"$ctl" record stop --server "$addr" >"$work/record.txt" || fails=$((fails + 1))
check "the shift recorded lane 0's lines" grep -qE "ended: [1-9][0-9]* lines" "$work/record.txt"
expect_error "a second stop" "no recording is running" "$ctl" record stop --server "$addr"
expect_error "a bad lane list" "--lanes must be lane ids separated by commas (got '0,x')" \
  "$ctl" record start --server "$addr" --lanes 0,x --minutes 1
"$ctl" process "$work/data/recordings/cli-shift/lane0" --out "$work/shift-out" --images none \
  >"$work/shift.txt" 2>&1 || fails=$((fails + 1))
check "the recorded shift replays" grep -q "^lane 0: .* 1 fillets" "$work/shift.txt"
"$ctl" status --server "$addr" >"$work/status.txt" || fails=$((fails + 1))
check "status shows latencies" grep -q "latency last_line_to_decision" "$work/status.txt"
"$ctl" lanes --server "$addr" >"$work/lanes.txt" || fails=$((fails + 1))
check "lanes listed" grep -q "^lane 3:" "$work/lanes.txt"
check "an empty list says so" grep -q "^no calibrations uploaded for lane 2" \
  <<<"$("$ctl" calib list --server "$addr" --lane 2)"
check "no learned settings yet" grep -q "^no learned settings" \
  <<<"$("$ctl" learned list --server "$addr")"
printf 'laser_plane: {normal: [0, 1, 0], offset_mm: 0.02}\n' >"$work/cal.yaml"
"$ctl" calib upload --server "$addr" --lane 1 --id cal-7 --file "$work/cal.yaml" >/dev/null || fails=$((fails + 1))
expect_error "activation without a report is refused" "has no report" \
  "$ctl" calib activate --server "$addr" --lane 1 --id cal-7
"$ctl" calib activate --server "$addr" --lane 1 --id cal-7 --force >/dev/null || fails=$((fails + 1))
check "calibration listed active" grep -q "cal-7 *active" <<<"$("$ctl" calib list --server "$addr")"
printf 'xray: {pitch_mm: -1}\n' >"$work/badcal.yaml"
expect_error "malformed calibration" "xray.pitch_mm: must be > 0" \
  "$ctl" calib upload --server "$addr" --lane 1 --id bad --file "$work/badcal.yaml"
# Live product learning on two lanes at once, from their next fillets: too few to learn
# from, so each stores a failed version and the command exits 2; then lane 0 learns again
# from the same fillets without waiting.
"$ctl" learned learn --server "$addr" --lanes 0,1 --fillets 3 --id cli-learn \
  --timeout 300 >"$work/learn.txt" 2>&1 &
learner=$!
sleep 1
"$ctl" feed --server "$addr" --simulate --lanes 2 --fillets 5 --seed 5 --encoder-start 50000000 \
  >/dev/null || fails=$((fails + 1))
wait $learner
rc=$?
check "a live learning that failed exits 2" test $rc -eq 2
check "both lanes stored a version" test "$(grep -c "cli-learn .*report: the learning failed" "$work/learn.txt")" -eq 2
check "and say so" grep -q "2 of 2 lanes' learning failed" "$work/learn.txt"
"$ctl" learned learn --server "$addr" --lane 0 --relearn-from cli-learn --id cli-again \
  >"$work/again.txt" 2>&1
check "lane 0 learns again from the same fillets" grep -q "^lane 0  cli-again" "$work/again.txt"
expect_error "a run the lane does not keep is refused" "the fillets it keeps are those of 'cli-learn'" \
  "$ctl" learned learn --server "$addr" --lane 0 --relearn-from nothing-like-it
kill -TERM $pid
wait $pid
check "graceful stop" grep -q "rangexd: stopped after" "$work/rangexd.log"
start_rangexd "$work/rangexd2.log"
check "results kept across a restart" test "$("$ctl" fillets --server "$addr" | wc -l)" -ge 2
kill -TERM $pid
wait $pid

# The tamper-evident record: the store's chain verifies, an export proves its links by
# hashing alone (checked here with Python's hashlib), and a decision changed behind the
# store's back is named.
out=$("$ctl" audit verify --data "$work/data")
check "audit chain verifies ($out)" grep -q "^chain verified: [1-9][0-9]* links" <<<"$out"
"$ctl" audit export --data "$work/data" --out "$work/chain.jsonl" >/dev/null || fails=$((fails + 1))
check "the export's links hash as they say" /usr/bin/python3 - "$work/chain.jsonl" <<'PY'
import hashlib, json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
prev = rows[0]["prev"]
for r in rows[1:-1]:
    assert r["prev"] == prev, r["seq"]
    assert hashlib.sha256((r["prev"] + "\n" + r["content"]).encode()).hexdigest() == r["hash"], r["seq"]
    prev = r["hash"]
assert prev == rows[-1]["head"] and len(rows) > 3
PY
/usr/bin/python3 -c "import sqlite3,sys; db=sqlite3.connect(sys.argv[1]); db.execute(\"UPDATE fillets SET decision='pass' WHERE uid=1\"); db.commit()" "$work/data/rangex.sqlite"
expect_error "a changed decision breaks the chain" "fillet 1 was changed after it was recorded" \
  "$ctl" audit verify --data "$work/data"

expect_error "unknown method" "unknown stripe method 'median'" \
  "$ctl" process "$work/rec" --out "$work/o2" --method median
printf 'lanes:\n  - id: 0\n    frame: {width: 320, height: 200}\n' >"$work/small.yaml"
expect_error "wrong frame size" "recording frames are 640x200 but the plant configuration says 320x200" \
  "$ctl" process "$work/rec" --out "$work/o3" --config "$work/small.yaml"
printf 'lanes: [ {id: 0\n' >"$work/bad.yaml"
expect_error "bad yaml" "not valid YAML" "$ctl" process "$work/rec" --out "$work/o4" --config "$work/bad.yaml"
expect_error "unknown lane" "unknown lane 7" "$ctl" extract "$work/rec" --lane 7 --camera 0 --out "$work/p.csv"
expect_error "unknown option" "unknown option --fillet" "$ctl" simulate --fillet 3 --out "$work/x"
truncate -s -1000 "$work/rec/lane0/xray.u16"
expect_error "truncated recording" "xray.u16 is truncated" "$ctl" process "$work/rec" --out "$work/o5"

# `rangexctl CMD --help`: that command's entries of the usage, under their section's heading.
has() { grep -qE -- "$1" <<<"$help"; }
lacks() { ! has "$1"; }
help=$("$ctl" learn --help); rc=$?
check "learn --help exits 0" test $rc -eq 0
check "and shows learn's entry" has "^  learn RECORDING --out PLANT.yaml"
check "and no other command's" lacks "^  (simulate|process|eval|calib) "
help=$("$ctl" eval --help)
check "eval --help shows eval" has "^  eval DIR OUT"
check "and not eval-matrix" lacks "eval-matrix"
help=$("$ctl" feed --recording x -h)
check "a server command's help shows it" has "^  feed \\(--recording"
check "and how to reach the server" has "--server HOST:PORT"
check "and its TLS options" has "--ca CA.pem"
help=$("$ctl" bench --help)
check "bench --help sits under the benchmarks" has "^benchmarks"
check "not under the calibration" lacks "calibration of a lane"
# Every option the usage names is one its command takes (the usage once offered
# `calib camera --fix-skew`, an option that command did not know). A command's entry is its
# line and the lines indented under it; its options are given to it at once, with bad values
# (an unknown option is refused before any value is read).
usage=$("$ctl" help 2>&1)
# A lowercase second word is a subcommand (`calib camera`); else the command is one word.
commands=$(grep -E "^  [a-z]" <<<"$usage" | awk '{ print ($2 ~ /^[a-z]/) ? $1 " " $2 : $1 }' | sort -u)
tried=0
while read -r cmd; do
  args=()
  for opt in $(awk -v c="  $cmd " 'index($0, c) == 1 { on = 1; print; next }
      on && /^      / { print; next } { on = 0 }' <<<"$usage" | grep -oE -- "--[a-z][a-z0-9-]*" | sort -u); do
    args+=("$opt" x)
    tried=$((tried + 1))
  done
  [ ${#args[@]} -eq 0 ] && continue
  out=$(timeout 20 "$ctl" $cmd nowhere "${args[@]}" 2>&1)
  check "$cmd takes every option the usage names" bash -c '! grep -q "unknown option" <<<"$1"' _ "$out"
done <<<"$commands"
check "the usage's options were tried ($tried)" test "$tried" -gt 100
"$ctl" nosuch --help >/dev/null 2>&1
check "an unknown command's --help is refused (exit 2)" test $? -eq 2

[ $fails -eq 0 ] && echo "cli: all checks passed" || echo "cli: $fails checks failed"
exit $((fails > 0))
