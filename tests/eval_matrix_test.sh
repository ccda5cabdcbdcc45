#!/usr/bin/env bash
# A slice of the evaluation matrix: two plant variants, each calibrated from its
# own scenes and inspected; the figures are parsed from matrix.json. The full matrix is a
# benchmark (rangexctl eval-matrix, minutes per variant) and runs outside CI.
set -u
ctl="$1"
source "$(dirname "$0")/script_checks.sh"
# Beside them a variant that cannot run: it is reported as failed, the others still run, and
# the command says so by its exit status (2).
mkdir -p vars
cp "$(dirname "$RANGEX_CONFIG")"/variants/{strong_blur,steep_edges}.yaml vars/
printf 'name: broken\nbones: {probability: 7}\n' >vars/broken.yaml
# The same in a file whose name is not UTF-8 (a failed variant is named by its file).
cp vars/broken.yaml vars/$'broken\xff.yaml'
# And one whose name holds a quote and a backslash: matrix.json must still be JSON.
sed 's/^name: .*/name: '"'"'odd "blur" \\ 2'"'"'/' vars/strong_blur.yaml >vars/odd.yaml
"$ctl" eval-matrix --out m --variants vars --only broken,$'broken\xff',strong_blur,steep_edges,odd --fillets 8 \
  --seed 3 --learn 0 >run.txt 2>&1
rc=$?
[ -s m/matrix.json ] || { echo "FAIL eval-matrix (status $rc)"; cat run.txt; exit 1; }
cat m/matrix.txt
py() { python3 -c "import json,sys; m=json.load(open('m/matrix.json')); v={x['name']: x for x in m['variants']}; sys.exit(0 if ($1) else 1)"; }
check "a variant that fails says so by the exit status" test "$rc" -eq 2
check "it is reported failed, naming what is wrong" py "'probability' in v['broken']['failed']"
check "the matrix text names it" grep -q "failed: broken" m/matrix.txt
check "a name that is not UTF-8 is written with U+FFFD for its byte" py "'probability' in v['broken\\ufffd']['failed']"
check "the variants evaluated" py "set(v) - {'broken', 'broken\\ufffd'} == {'strong_blur', 'steep_edges', 'odd \"blur\" \\\\ 2'} and all('failed' not in x for k, x in v.items() if not k.startswith('broken'))"
check "every figure is a number" py "all(isinstance(x[k], (int, float)) for x in v.values() if 'failed' not in x for k in ('thickness_mean_abs_mm', 'residual_std_dn', 'recall_calcified_ge_2mm', 'false_reject_rate', 'position_mean_mm', 'baseline_recall_calcified_ge_2mm'))"
check "how rough each plant is: its residual's spread in DN, as smooth meat leaves it (the nominal simulator: 18.6)" py "all(5 < v[k]['residual_std_dn'] < 100 for k in ('strong_blur', 'steep_edges'))"
check "the matrix text gives it" grep -qE "^strong_blur +[0-9.]+ +[-+][0-9.]+ +[0-9]+\.[0-9] \|" m/matrix.txt
check "strong blur: thickness within 0.1 mm after its own calibration" py "v['strong_blur']['thickness_mean_abs_mm'] <= 0.1"
check "rangex recalls at least what the X-ray alone does" py "all(x['recall_calcified_ge_2mm'] >= x['baseline_recall_calcified_ge_2mm'] for x in v.values() if 'failed' not in x)"
check "the variant's own calibration says where K1/K2 come from" grep -q "fitted_on: \"calib scatter on" m/strong_blur/lane0.yaml
check "the blur measured on the variant's pins" grep -q "detector_sigma_px: 0.9" m/strong_blur/lane0.yaml
check "the scans are gone once evaluated" test ! -e m/strong_blur/rec
# With learning: the variant's own clean fillets learned, its claims checked on
# others, a clean run and a bone run inspected with what was learned (too few fillets to pass
# the learning's gate: the matrix forces it, and says so).
"$ctl" eval-matrix --out l --only rough_meat --fillets 4 --seed 5 --learn 12 --check 3 --frr 3 --frr-part 2 --bones 3 \
  --confidence 0.8 >learn.txt 2>&1 || { echo "FAIL eval-matrix --learn"; cat learn.txt; exit 1; }
cat l/matrix.txt
pl() { python3 -c "import json,sys; m=json.load(open('l/matrix.json')); v=m['variants'][0]; L=v['learned']; sys.exit(0 if ($1) else 1)"; }
check "the learned run is reported" pl "L['learning_fillets'] == 12 and not L['ok']"
check "learned at the confidence asked for" python3 -c "import json,sys; j=json.load(open('l/rough_meat/learned.report/learn.json')); sys.exit(0 if [x['confidence'] for x in j['lanes']] == [0.8] else 1)"
check "its clean run counted over its two parts" pl "L['clean_run']['fillets'] == 3"
check "each part inspected, its scan dropped" bash -c "test -d l/rough_meat/out_frr0 && test -d l/rough_meat/out_frr1 && test ! -e l/rough_meat/out_frr2 && test ! -e l/rough_meat/frr_rec && test ! -e l/rough_meat/learn_rec"
check "the report's sentences checked on the check fillets" pl "0 <= L['stated_held'] <= L['stated'] and 0 <= L['stated_pieces'][0] <= L['stated_pieces'][1] and (L['stated'] == 0) == (L['stated_pieces'][1] == 0)"
check "a claim not held says whether its shortfall is evidence against it" pl "0 <= L['claims_contradicted'] <= L['claims'] - L['claims_held']"
check "the learning's check says so claim by claim" python3 -c "import json,sys; h=json.load(open('l/rough_meat/learned.report/learn.json'))['lanes'][0]['held_out_check']; sys.exit(0 if all(0 <= k['p_at_rate'] <= 1 and k['contradicted'] == (k['p_at_rate'] < 0.05) and (k['held'] or k['injected'] == 0 or 'of checks' in k['text']) for k in h['checks']) and h['contradicted'] == sum(k['contradicted'] for k in h['checks']) else 1)"
check "fillets the learning named are each kept (clean by the truth) or left out" pl "L['named'] == L['kept_checked_clean'] + L['left_out_bony'] and L['left_out_bony'] == 0"
check "recall and false rejects as counts" pl "len(L['recall_calcified_ge_2mm']) == 2 and len(L['false_rejects']) == 2"
check "the learned configuration was written and used" grep -q "learned:" l/rough_meat/learned.yaml
check "the drift monitor followed the clean run's passed fillets, its parts in order" pl "L['clean_run']['drift']['passed'] == L['clean_run']['fillets'] - L['clean_run']['rejected'] and not L['clean_run']['drift']['drifting'] and L['clean_run']['drift']['first_flagged'] == -1"
check "the matrix says what it said" grep -qE "lane 0: drift monitor: [0-9]+ passed fillets, fewer than the 200" l/matrix.txt
check "the learning's report beside it" test -s l/rough_meat/learned.report/learn.json
B="L['bone_run']"
check "the bone run judged over its two parts" pl "$B['fillets'] == 3 and 0 <= $B['recall_calcified_ge_2mm'][0] <= $B['recall_calcified_ge_2mm'][1] and len($B['missed']) == $B['recall_calcified_ge_2mm'][1] - $B['recall_calcified_ge_2mm'][0] and all('seed' in m for m in $B['missed'])"
check "each bone part inspected with the learned thresholds, its scan dropped" bash -c "test \$(tail -n +2 l/rough_meat/out_bones0/lane0/fillets.csv | wc -l) -eq 2 && test \$(tail -n +2 l/rough_meat/out_bones1/lane0/fillets.csv | wc -l) -eq 1 && test ! -e l/rough_meat/bone_rec"
check "the matrix pools it with the plant's fragments" grep -q "rough_meat: 3 fillets: calcified >= 2 mm" l/matrix.txt
check "the chances of the calcified fragments >= 2 mm, plant and bone run, summed over those weighed" pl "0 <= $B['bone_allows'][0] <= $B['bone_allows'][1] <= $B['recall_calcified_ge_2mm'][1] + L['recall_calcified_ge_2mm'][1] and len(L['fragment_chances']) == $B['bone_allows'][1] and abs(sum(f['chance'] for f in L['fragment_chances']) - $B['bone_allows'][0]) < 1e-3"
C="L['claims_on_fragments']"
check "the report's sphere claims held against the plant's and the bone run's own fragments, each weighed by its truth" pl "$C['weighed'] > 0 and $C['unknown'] == 0 and 0 <= $C['found'] <= $C['covered'] <= $C['weighed'] and 0 <= $C['dense_found'] <= $C['dense_covered'] <= $C['covered'] and len($C['missed']) == $C['covered'] - $C['found']"
check "the matrix says how many of them were found" grep -qE "^rough_meat: [0-9]+/[0-9]+ found of the compact fragments its sphere claims cover" l/matrix.txt
A="L['acceptance']"
check "held against the targets with every fillet of the run pooled: the plant's, the clean run's, the bone run's" pl "$A['false_rejects'] == [L['false_rejects'][0] + L['clean_run']['rejected'] + $B['false_rejects'][0], L['false_rejects'][1] + L['clean_run']['fillets'] + $B['false_rejects'][1]] and $A['no_bone'] == [L['false_fragments'] + L['clean_run']['fragments'] + $B['false_fragments'], L['fillets'] + L['clean_run']['fillets'] + $B['fillets']] and $A['recall_calcified_ge_2mm'] == [L['recall_calcified_ge_2mm'][0] + $B['recall_calcified_ge_2mm'][0], L['recall_calcified_ge_2mm'][1] + $B['recall_calcified_ge_2mm'][1]]"
check "a handful of clean fillets cannot show 0.5 % false rejects, so the run is not met" pl "$A['false_rejects'][1] < 253 and not $A['false_rejects_met'] and not $A['met'] and $A['false_reject_upper'] > 0.015"
check "recall judged only on a plant without needles, rib plates or cartilage" pl "$A['recall_judged'] == ($A['recall_exempt'] == '' and $A['recall_calcified_ge_2mm'][1] > 0) and ($A['recall_exempt'] == '') == ($A['needles'] + $A['ribs'] + $A['cartilage'] == 0)"
check "the matrix text gives the verdict and its figures" bash -c "grep -qE '^rough_meat: not met$' l/matrix.txt && grep -qE '^  clean fillets rejected [0-9]+/[0-9]+ = [0-9.]+ % \\[[0-9.]+-[0-9.]+ %\\]: not ' l/matrix.txt"
"$ctl" eval-matrix --out x --only rough_meat --learn 0 --bones 2 >bones0.txt 2>&1
check "a bone run without learning is refused, saying why" grep -q "bones inspects with the learned thresholds" bones0.txt
"$ctl" eval-matrix --out x --only rough_meat --confidence 0.3 >conf.txt 2>&1
check "a confidence learn would refuse is refused before anything runs" bash -c "grep -q \"confidence must be a number within 0.5..0.999 (got '0.3')\" conf.txt && test ! -e x/rough_meat"
# A lane on the shipped constants is warned about; the plant's own calibration silences it.
"$ctl" simulate --out rec --lanes 1 --fillets 1 --seed 4 >/dev/null 2>&1
"$ctl" process rec --out p1 --images none >p1.txt 2>&1
check "process warns of constants never fitted on the rig" grep -q "never fitted on its own rig" p1.txt
"$ctl" process rec --out p2 --images none --calibration m/strong_blur/lane0.yaml >p2.txt 2>&1
check "not once they are fitted" bash -c "! grep -q 'never fitted on its own rig' p2.txt"
echo "$fails failed"
exit $((fails > 0))
