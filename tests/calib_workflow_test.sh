#!/usr/bin/env bash
# The integrator's calibration workflow through rangexctl on a simulated rig that differs
# from plant.yaml (--rig-seed): target images, staircase, pin phantom and blocks are
# scanned, each part is solved into one lane calibration, and `calib validate` measures
# the staircase and blocks with it. The solved values are compared with the rig's truth.
set -u
ctl="$1"
table9=$(realpath "$2")  # the dissertation's pin measurements (appendix F)
source "$(dirname "$0")/script_checks.sh"
run() { "$@" >>log.txt 2>&1 || { echo "FAIL: $*"; tail -20 log.txt; exit 1; }; }
near() { awk -v a="$1" -v b="$2" -v t="$3" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(d <= t) }'; }
key() { grep -m1 "$2" "$1" | sed 's/.*: //'; }  # key FILE PATTERN: the value after ': '

for s in staircase pins blocks; do run "$ctl" calib simulate "$s" "$s" --rig-seed 3; done
# The blocks once more, elsewhere on the belt, to validate the registration with.
run "$ctl" calib simulate blocks blocks2 --rig-seed 3 --seed 2
run "$ctl" calib simulate targets t0 --cam 0 --rig-seed 3 --views 30
run "$ctl" calib simulate targets t1 --cam 1 --rig-seed 3 --views 30
run "$ctl" calib camera t0 --skip-unfound --out lane0.yaml
run "$ctl" calib camera t1 --skip-unfound --calibration lane0.yaml
check "camera solve wrote the calibration" test -f lane0.yaml
check "camera report beside it" test -f lane0.yaml.reports/camera-lane_0_cam0.json
check "uncertainty map written" test -f lane0.yaml.cam0-uncertainty.png
run "$ctl" calib staircase staircase --calibration lane0.yaml
run "$ctl" calib xray pins --calibration lane0.yaml
run "$ctl" calib registration blocks --calibration lane0.yaml
for png in lane0.yaml.cam0-residuals.png lane0.yaml-steps.png lane0.yaml.xray-pins.png; do
  check "report plot $png" test -s "$png"
done

truth=staircase/lane0/truth/rig.yaml
src_t=$(key "$truth" "source_mm" | tr -d '[],' | awk '{print $1, $2}')
src_f=$(key lane0.yaml "source_mm" | tr -d '[],' | awk '{print $1, $2}')
check "source x within 0.2 mm of the rig's" near "$(echo "$src_f" | cut -d' ' -f1)" "$(echo "$src_t" | cut -d' ' -f1)" 0.2
check "source z within 0.2 mm of the rig's" near "$(echo "$src_f" | cut -d' ' -f2)" "$(echo "$src_t" | cut -d' ' -f2)" 0.2
check "detector offset within 0.2 mm" near "$(key lane0.yaml first_pixel_x_mm)" "$(key "$truth" first_pixel_x_mm)" 0.2
plane=$(key blocks/lane0/truth/optics.yaml plane_y_mm)
check "delay is the rig's" test "$(key lane0.yaml delay_lines)" = "$(awk -v p="$plane" 'BEGIN { printf "%d", p / 0.4 + 0.5 }')"

out=$("$ctl" calib validate staircase --calibration lane0.yaml 2>&1); rc=$?
echo "$out" | grep "worst step"
check "validate: staircase within 0.1 mm on both cameras" \
  test "$(echo "$out" | awk '/worst step error/ { if ($6 > 0.1) bad = 1 } END { print bad + 0 }')" = 0
check "validate exits 0" test $rc -eq 0
out=$("$ctl" calib validate staircase 2>&1); rc=$?
echo "$out" | grep "worst step" | sed 's/^/  plant.yaml: /'
check "validate fails with plant.yaml's calibration on the moved rig" test $rc -eq 2
# Laser-to-X-ray: the cameras were moved into the X-ray's frame by the staircase's
# placement, and block corners placed elsewhere agree in both images.
offset=$(grep '"lateral_offset_mm"' lane0.yaml.reports/registration-lane_0.json | sed 's/.*"value": \([^,]*\),.*/\1/')
placed=$(key staircase/lane0/truth/placement.yaml staircase_offset_mm)
echo "  registration: cameras moved ${offset} mm across the belt; the staircase stood ${placed} mm off its drawing"
check "registration finds the staircase's placement within 0.1 mm" near "$offset" "$placed" 0.1
out=$("$ctl" calib validate blocks2 --calibration lane0.yaml 2>&1); rc=$?
echo "$out" | grep "corners"
check "validate: block corners laser vs X-ray within 0.1 mm mean" \
  test "$(echo "$out" | awk '/corners, laser vs X-ray/ { print ($10 <= 0.1) }')" = 1
check "validate blocks exits 0" test $rc -eq 0

# End to end: the same plant (seed) rendered through the nominal rig and through the moved
# rig; the moved one replayed with plant.yaml and with the solved calibration.
run "$ctl" simulate --lanes 1 --fillets 16 --seed 5 --rig-seed 3 --out moved
run "$ctl" simulate --lanes 1 --fillets 16 --seed 5 --out nominal
# K1/K2 from the plant's own recording (its truth stands in for coated reference profiles).
run "$ctl" calib scatter moved --calibration lane0.yaml
check "scatter report beside the calibration" test -f lane0.yaml.reports/scatter-lane_0_cam1.json
run "$ctl" process nominal --out out_nominal --images none
run "$ctl" process moved --out out_plain --images none
run "$ctl" process moved --out out_solved --images none --calibration lane0.yaml
for r in nominal:nominal moved:plain moved:solved; do
  "$ctl" eval "${r%%:*}" "out_${r##*:}" >"eval_${r##*:}.txt" || fails=$((fails + 1))
done
thick() { awk '$1 == "0" { print $10 }' "eval_$1.txt"; }       # thickness mean |error|, mm
bias() { awk '$1 == "0" { print $12 }' "eval_$1.txt"; }
pct() { grep "$2" "eval_$1.txt" | awk '{ v = $(NF-1); sub("%", "", v); print v }'; }
for r in nominal plain solved; do
  echo "  $r: thickness mean|e| $(thick $r) mm, bias $(bias $r) mm, recall >= 2 mm $(pct $r 'recall, calcified') %," \
    "false rejects $(pct $r 'false rejects') %, bone fillets rejected $(pct $r 'fillets with bone') %"
done
check "plant.yaml on the moved rig is far off (5x the calibrated error or more)" \
  awk -v a="$(thick plain)" -v b="$(thick solved)" 'BEGIN { exit !(a >= 5 * b) }'
check "calibrated thickness error within 0.03 mm of the nominal rig's" \
  awk -v a="$(thick solved)" -v b="$(thick nominal)" 'BEGIN { exit !(a <= b + 0.03) }'
check "calibrated thickness bias within 0.03 mm" near "$(bias solved)" 0 0.03
check "calibrated recall of calcified fragments as the nominal rig's" \
  test "$(pct solved 'recall, calcified')" = "$(pct nominal 'recall, calcified')"
check "calibrated false rejects no more than the nominal rig's" \
  awk -v a="$(pct solved 'false rejects')" -v b="$(pct nominal 'false rejects')" 'BEGIN { exit !(a <= b) }'

# The solved set with its reports goes to a running rangexd and is activated: the reports
# passed, so no --force is needed; a hand-made set without reports is refused.
srv="$(dirname "$ctl")/../server/daemon/rangexd"
"$srv" --listen 127.0.0.1:0 --http 127.0.0.1:0 --data "$work/data" >rangexd.log 2>&1 &
pid=$!
for _ in $(seq 600); do grep -q "listening on" rangexd.log && break; kill -0 $pid 2>/dev/null || break; sleep 0.1; done
addr=$(sed -nE 's/.*listening on ([0-9.]+:[0-9]+).*/\1/p' rangexd.log)
up=$("$ctl" calib upload --server "$addr" --lane 0 --id solved --file lane0.yaml 2>&1)
check "upload carries the reports" grep -q "report: passed" <<<"$up"
check "activation of a passed set" "$ctl" calib activate --server "$addr" --lane 0 --id solved
check "show prints the report" grep -q '"solver": "registration"' \
  <<<"$("$ctl" calib show --server "$addr" --lane 0 --id solved)"
printf 'laser_plane: {normal: [0, 1, 0], offset_mm: 0.0}\n' >hand.yaml
"$ctl" calib upload --server "$addr" --lane 0 --id hand --file hand.yaml >/dev/null
out=$("$ctl" calib activate --server "$addr" --lane 0 --id hand 2>&1); rc=$?
check "a set without a report is refused" test $rc -eq 1
check "the refusal says why" grep -q "has no report" <<<"$out"
kill -TERM $pid
wait $pid

# Table 9's real pins: the fan beam with tilt and per-row offsets against a plain one.
full=$("$ctl" calib xray --pins "$table9" --hold-pitch --row-offsets 2>/dev/null | grep "^# fan beam")
plain=$("$ctl" calib xray --pins "$table9" --hold-pitch --no-tilt 2>/dev/null | grep "^# fan beam")
echo "  Table 9, full model: ${full#\# fan beam: }"
echo "  Table 9, plain fan:  ${plain#\# fan beam: }"
rms() { sed -E 's/.*RMS ([0-9.]+) px.*/\1/' <<<"$1"; }
check "Table 9: the full model's RMS below the plain fan beam's" \
  awk -v a="$(rms "$full")" -v b="$(rms "$plain")" 'BEGIN { exit !(a < b) }'

out=$("$ctl" calib camera staircase 2>&1); rc=$?
check "camera on a folder without board.yaml is refused" test $rc -eq 1
rm -f pins/pin_phantom.yaml
out=$("$ctl" calib xray pins 2>&1); rc=$?
check "xray without the phantom's drawing names it" grep -q "pin_phantom.yaml" <<<"$out"

# Dual energy: the step wedge scanned on the belt and fitted into the lane calibration; a
# lane of one energy refuses both.
sed 's/^    bits: 12$/    bits: 12\n    energies: 2/' "$RANGEX_CONFIG" > dual.yaml
run "$ctl" calib simulate dual-energy wedge --config dual.yaml
run "$ctl" calib dual-energy wedge --config dual.yaml --calibration lane0.yaml --out dual0.yaml
check "dual-energy fit written into the lane calibration" grep -q "^  dual_energy:" dual0.yaml
check "its report beside it" test -f dual0.yaml.reports/dual-energy-lane_0.json
check "the wedge recovered within 1 %" grep -q '"passed": true' dual0.yaml.reports/dual-energy-lane_0.json
out=$("$ctl" calib dual-energy wedge --calibration lane0.yaml 2>&1); rc=$?
check "a lane of one energy refuses the wedge" test $rc -eq 1
check "naming why" grep -q "has one X-ray energy" <<<"$out"

echo "$fails failed"
exit $((fails > 0))
