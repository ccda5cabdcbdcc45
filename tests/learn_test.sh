#!/usr/bin/env bash
# rangexctl learn through its command line: a lane learned from a recording of
# clean product writes a plant configuration that process uses as is, with its report;
# the same run learns the same thresholds again (fixed seeds), its whitened kernels with them; what
# other false-reject targets would buy (thresholds, test pieces found) moves one way; a
# learning run that holds bone is refused and names the fillets; bad options name themselves.
set -u
ctl="$1"
source "$(dirname "$0")/script_checks.sh"

# The recording's name holds a byte that is not UTF-8, as a Linux path may: the report still
# names it (as U+FFFD), where the learning once ended after all its work on a JSON exception.
rec=$'clean\xff'
"$ctl" simulate --clean --lanes 1 --fillets 14 --seed 31 --out "$rec" >/dev/null 2>&1 \
  || { echo "FAIL simulate clean"; exit 1; }
learn() { "$ctl" learn "$rec" --min-fillets 10 --bootstrap 30 --version t1 "$@"; }
learn --out learned.yaml >learn.txt 2>&1
rc=$?
cat learn.txt
check "learning on clean product succeeds" test $rc -eq 0
check "the plant configuration is written" grep -q "learned:" learned.yaml
check "with its version" grep -q 'version: "\?t1' learned.yaml
check "and the budget" grep -q "false_reject_target: 0.003" learned.yaml
check "the report" test -s learned.report/learn.json
for p in thresholds sensitivity qq; do check "the $p plot" test -s learned.report/lane0_$p.png; done
py() { python3 -c "import json,sys; j=json.load(open('learned.report/learn.json')); l=j['lanes'][0]; sys.exit(0 if ($1) else 1)"; }
check "report ok with 14 fillets" py "j['ok'] and l['fillets'] == 14"
check "it names the recording, its byte that is not UTF-8 as U+FFFD" py "j['recording'].endswith('clean\\ufffd')"
check "round thresholds per band, all finite and positive" py "len(l['statistics']['round']['thresholds']) == len(l['band_edges_mm']) - 1 and all(0 < t < 100 for t in l['statistics']['round']['thresholds'])"
check "the thresholds spend at most the budget" py "l['statistics']['round']['implied_frr'] + l['statistics']['needle']['implied_frr'] <= 0.003"
imp=$(python3 -c "import json; l=json.load(open('learned.report/learn.json'))['lanes'][0]; print('%.3f' % (100 * (l['statistics']['round']['implied_frr'] + l['statistics']['needle']['implied_frr'])))")
check "the output says what they spend together" grep -q "together: implied $imp % of fillets, of the 0.30 % asked" learn.txt
check "test pieces were injected and some found" py "sum(c['injected'] for c in l['sensitivity']['cells']) > 100 and sum(c['found'] for c in l['sensitivity']['cells']) > 0"
check "every claim stands on its detection curve's lower bound and on the rate found" py "all(c['pod_lower'] >= l['sensitivity']['rate'] and any(x['shape'] == c['shape'] and x['band'] == c['band'] and x['size_mm'] == c['size_mm'] and x['found'] >= 0.95 * x['injected'] for x in l['sensitivity']['cells']) for c in l['sensitivity']['claims_95'])"
check "large spheres are found in every band they were put in" py "all(c['found'] >= 0.9 * c['injected'] for c in l['sensitivity']['cells'] if c['shape'] == 'sphere' and c['size_mm'] >= 4)"
# What other false-reject targets buy, on the same fillets and test pieces. The second run
# also shows that learning is exact with fixed seeds: it writes the first run's file.
learn --out to.yaml --tradeoff 0.001,0.03 >to.txt 2>&1
rc=$?
sed -n '/what each false-reject target buys/,$p' to.txt
check "learning with a trade-off succeeds" test $rc -eq 0
check "learning is exact with fixed seeds: the lane's own target learned as before" diff -q learned.yaml to.yaml
check "the output says what each target buys" grep -q "what each false-reject target buys" to.txt
pt() { python3 -c "
import json, sys
l = json.load(open('to.report/learn.json'))['lanes'][0]
p = {x['target_frr']: x for x in l['tradeoff']}
p[0.003] = {'cells': l['sensitivity']['cells'], 'implied_frr': l['statistics']['round']['implied_frr'] + l['statistics']['needle']['implied_frr'],
            'thresholds': {s: l['statistics'][s]['thresholds'] for s in ('round', 'needle')}}
t = sorted(p)
sys.exit(0 if ($1) else 1)"; }
check "a point for each target asked and the lane's" pt "t == [0.001, 0.003, 0.03]"
check "each target's thresholds imply no more than it" pt "all(p[x]['implied_frr'] <= x * (1 + 1e-9) for x in t)"
check "a higher target lowers the thresholds" pt "all(all(u >= v for u, v in zip(p[a]['thresholds'][s], p[b]['thresholds'][s])) and p[a]['thresholds'][s] != p[b]['thresholds'][s] for a, b in zip(t, t[1:]) for s in ('round', 'needle'))"
check "and finds every test piece the lower one found" pt "all(c['found'] >= {(d['shape'], d['size_mm'], d['band']): d['found'] for d in p[a]['cells']}[(c['shape'], c['size_mm'], c['band'])] for a, b in zip(t, t[1:]) for c in p[b]['cells'])"
out=$("$ctl" learn "$rec" --out bad.yaml --tradeoff 0.001,0.7 2>&1)
rc=$?
check "a trade-off target beyond range is refused naming it" bash -c "[ $rc -eq 1 ] && grep -q -- '--tradeoff: expected' <<<'$out'"
"$ctl" process "$rec" --config learned.yaml --out out --images none >process.txt 2>&1
check "process uses the learned configuration as is" test $? -eq 0
check "it says what the lane's drift monitor would (too few fillets to say here)" \
  grep -qE "lane 0: drift monitor: [0-9]+ passed fillets, fewer than the 200 it needs to say" process.txt
check "and writes it to the summary" python3 -c "
import json, sys
d = json.load(open('out/summary.json'))['lanes'][0]['drift']
sys.exit(0 if 0 < d['passed'] < 200 and not d['drifting'] and d['first_flagged'] == -1 and 0 < d['learned_frr'] <= 0.003 else 1)"
check "every passed fillet's band extremes beside the records" python3 -c "
import csv, sys
f = list(csv.DictReader(open('out/lane0/fillets.csv')))
e = list(csv.DictReader(open('out/lane0/extremes.csv')))
passed = {r['fillet'] for r in f if r['decision'] == 'pass'}
ok = passed and passed <= {r['fillet'] for r in e} and {r['statistic'] for r in e} <= {'round', 'needle', 'air'}
sys.exit(0 if ok and all(float(r['pixels']) >= 100 for r in e) else 1)"

# The kernels whitened by the product's own texture (inspection.matched_kernels_mm, by
# default 1.5, 2 and 3 mm spheres and 2 mm needles) travel with the learned settings, the void
# level learned with them; the trade-off run above learned them exactly again.
ky() { python3 -c "
import sys, yaml
m = yaml.safe_load(open('learned.yaml'))['lanes'][0]['inspection']['learned']['matched']
n = m['needles']
sys.exit(0 if ($1) else 1)"; }
check "the round kernels travel with the learned settings, the void level learned with them" \
  ky "m['sizes_mm'] == [1.5, 2, 3] and m['radii'] == [4] * 3 and m['clip'] == 0.5 and m['void_level'] > 0 and len(m['spreads']) == len(m['taps']) == 3 and all(len(t) == 81 for t in m['taps'])"
check "and the needle kernels, 8 directions of a 2 mm needle" \
  ky "n['diameter_mm'] == 0.6 and n['lengths_mm'] == [2] * 8 and n['angles_deg'] == [22.5 * k for k in range(8)] and len(n['spreads']) == len(n['taps']) == 8 and all(s > 0 for s in n['spreads'])"

# Bone in the learning run: refused, naming the fillets.
"$ctl" simulate --lanes 1 --fillets 14 --seed 32 --out boned >/dev/null 2>&1
"$ctl" learn boned --min-fillets 10 --bootstrap 20 --out boned.yaml >boned.txt 2>&1
rc=$?
cat boned.txt
check "a learning run with bone fails (exit 2)" test $rc -eq 2
check "it names the fillets" grep -q "fillet [0-9]* (belt [0-9]* mm) holds something like bone" boned.txt
check "and writes no configuration" test ! -e boned.yaml
check "refused without the test pieces: its report says the sensitivity was not measured" python3 -c "
import json, sys
s = json.load(open('boned.report/learn.json'))['lanes'][0]['sensitivity']
sys.exit(0 if s['measured_on'] == 'not measured' and not s['cells'] and s['summary'] == ['not measured: the learning failed'] else 1)"
check "and draws no sensitivity plot" test ! -e boned.report/lane0_sensitivity.png
check "and says --force would measure it" grep -q "with the sensitivity its thresholds buy" boned.txt
# The fillets it named, checked by an operator and kept in (--keep lane:fillet): the
# learning holds them as product and says so.
keep=$(grep -o "lane [0-9]* fillet [0-9]* (belt" boned.txt | awk '{printf "%s%s:%s", (NR > 1 ? "," : ""), $2, $4}')
"$ctl" learn boned --min-fillets 10 --bootstrap 20 --out kept.yaml --keep "$keep" >kept.txt 2>&1
rc=$?
cat kept.txt
check "with the named fillets kept ($keep) the learning holds (exit 0)" test $rc -eq 0
check "and says which it kept" grep -q "kept, checked clean: lane 0 fillet" kept.txt
check "the report lists them" python3 -c "import json,sys; l=json.load(open('kept.report/learn.json'))['lanes'][0]; sys.exit(0 if len(l['kept_checked_clean']) == len('$keep'.split(',')) and 'flagged_fillets' not in l else 1)"
out=$("$ctl" learn boned --out x.yaml --keep 0-3 2>&1); rc=$?
check "a fillet named badly is refused naming the option" bash -c "[ $rc -eq 1 ] && grep -q -- '--keep: expected LANE:FILLET' <<<'$out'"

out=$("$ctl" learn "$rec" --out x.yaml --target-frr 2 2>&1); rc=$?
check "a budget beyond range is refused naming it" bash -c "[ $rc -eq 1 ] && grep -q -- '--target-frr must be' <<<'$out'"
out=$("$ctl" learn "$rec" --out x.yaml --lanes 7 2>&1); rc=$?
check "an unknown lane is refused" bash -c "[ $rc -eq 1 ]"
echo "$fails failed"
exit $((fails > 0))
