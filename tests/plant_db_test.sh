#!/usr/bin/env bash
# Two rangexd forwarding to one real PostgreSQL (started here, initdb + pg_ctl), fed a
# simulated plant of 2 + 2 lanes: every record each server stores is in PostgreSQL exactly
# once, through a database stopped for 30 s mid-run and a rangexd killed with SIGKILL
# mid-forward; every server's chain verifies there, and an UPDATE behind rangex's back is
# named. The fleet view (rangexd --fleet) answers what the two servers' own dashboards answer
# together, fetches an image through the server that keeps it, and names that server when it
# cannot be reached. Both servers read one plant file that assigns them their lanes; a lane
# moved to the other server keeps one history. Usage: plant_db_test.sh RANGEXCTL RANGEXD
set -u
ctl="$1" srv="$2"
source "$(dirname "$0")/script_checks.sh"

bin=${RANGEX_PG_BIN:-$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)}
if [ ! -x "$bin/initdb" ]; then
  echo "FAIL PostgreSQL's initdb is not installed (Debian postgresql-15; scripts/install-deps.sh)"
  exit 1
fi
pg=$(mktemp -d /tmp/rangex-pg-XXXXXX)
as=""
if [ "$(id -u)" -eq 0 ]; then chown postgres "$pg"; as="runuser -u postgres --"; fi
pg_ctl() { (cd / && $as "$bin/pg_ctl" -D "$pg/data" "$@"); }
pids=()
trap 'kill -9 "${pids[@]}" 2>/dev/null; pg_ctl -m immediate -w stop >/dev/null 2>&1; rm -rf "$pg" "$work"' EXIT
(cd / && $as "$bin/initdb" -D "$pg/data" -A trust -U rangex -E UTF8 --no-sync) >"$work/initdb.log" 2>&1 ||
  { echo "FAIL initdb"; cat "$work/initdb.log"; exit 1; }
start_pg() { pg_ctl -l "$pg/server.log" -w -t 60 -o "-k $pg -p 5432 -c listen_addresses=" start >/dev/null; }
start_pg || { echo "FAIL PostgreSQL did not start"; exit 1; }
db="host=$pg port=5432 user=rangex dbname=postgres"
q() { psql "$db" -tAc "$1"; }

# The schema is rangexctl's to apply: from the previous version, then the rest.
"$ctl" db status --db "$db" >/dev/null
check "db status says an empty database is not ready (exit 1)" test $? -eq 1
"$ctl" db migrate --db "$db" --to 1 >/dev/null || fails=$((fails + 1))
"$ctl" db migrate --db "$db" >"$work/migrate.txt" || fails=$((fails + 1))
check "migrated from version 1" grep -q "applied migration 2" "$work/migrate.txt"
"$ctl" db status --db "$db" >/dev/null
check "db status: the schema this build needs" test $? -eq 0
"$ctl" db status --db "$db password=secret" >/dev/null 2>"$work/password.txt"
check "a password on the command line is refused" grep -q "\-\-db holds a password" "$work/password.txt"

# Two servers, two lanes each, from one plant file: lanes 0 and 1 are srv-a's, 2 and 3 srv-b's.
# Each feeder's file holds its server's lanes only.
base="${RANGEX_CONFIG:-$(dirname "$0")/../config/plant.yaml}"
plant_file() {  # plant_file OUT SERVER-OF-LANE-2
  sed -e "s|^  storage: .*|  storage: $work/data\n  results_db: \"$db\"\n  results_db_retry_max_s: 2|" \
      -e 's|^  - id: \([01]\)$|  - {id: \1, server: srv-a}|' \
      -e "s|^  - id: 2$|  - {id: 2, server: $2}|" \
      -e 's|^  - id: 3$|  - {id: 3, server: srv-b}|' "$base" >"$1"
}
plant_file "$work/plant.yaml" srv-b
sed -e '/^  - id: [23]$/d' "$base" >"$work/feed-a.yaml"
sed -e '/^  - id: [01]$/d' "$base" >"$work/feed-b.yaml"
start_server() {  # start_server a|b N [PLANT]: starts it, sets addr_a / addr_b, web_a / web_b
  local s=$1
  "$srv" --config "${3:-$work/plant.yaml}" --server-id "srv-$s" --data "$work/data-$s" \
    --listen 127.0.0.1:0 --http 127.0.0.1:0 >>"$work/rangexd-$s.log" 2>&1 &
  pids+=($!)
  eval "pid_$s=$!"
  for _ in $(seq 600); do
    [ "$(grep -c "listening on" "$work/rangexd-$s.log")" -ge "$2" ] && break
    sleep 0.1
  done
  eval "addr_$s=$(grep "listening on" "$work/rangexd-$s.log" | tail -1 | sed -nE 's/.*listening on ([0-9.]+:[0-9]+).*/\1/p')"
  eval "web_$s=$(grep "dashboard at" "$work/rangexd-$s.log" | tail -1 | sed -nE 's|.*dashboard at (http://[0-9.]+:[0-9]+)/.*|\1|p')"
}
start_server a 1
start_server b 1
check "both servers listen" test -n "$addr_a" -a -n "$addr_b"
check "srv-b runs the lanes the plant file names for it" grep -q "server srv-b runs lanes 2, 3" "$work/rangexd-b.log"
"$srv" --config "$work/plant.yaml" --server-id srv-z --listen 127.0.0.1:0 --http off >"$work/srv-z.log" 2>&1
check "a server the plant file names no lane for is refused" grep -q "assigns no lane to server 'srv-z'" "$work/srv-z.log"

# Lag drains: `status` says caught up with the whole chain.
caught_up() {  # caught_up ADDR SECONDS
  for _ in $(seq $((${2} * 5))); do
    "$ctl" status --server "$1" 2>/dev/null | grep -q "caught up, 0 records" && return 0
    sleep 0.2
  done
  return 1
}
"$ctl" feed --server "$addr_a" --config "$work/feed-a.yaml" --simulate --lanes 2 --fillets 2 --seed 3 >"$work/feed-a1.txt" || fails=$((fails + 1))
check "server a caught up" caught_up "$addr_a" 60
# A calibration version on server a's lane 1, activated: its history reaches the fleet view.
printf 'laser_plane: {normal: [0, 1, 0], offset_mm: 0.02}\n' >"$work/cal.yaml"
"$ctl" calib upload --server "$addr_a" --lane 1 --id cal-7 --file "$work/cal.yaml" >/dev/null || fails=$((fails + 1))
"$ctl" calib activate --server "$addr_a" --lane 1 --id cal-7 --force >/dev/null || fails=$((fails + 1))

# PostgreSQL stopped for 30 s mid-run: inspection goes on, the lag grows, then drains.
pg_ctl -m fast -w stop >/dev/null
"$ctl" feed --server "$addr_a" --config "$work/feed-a.yaml" --simulate --lanes 2 --fillets 2 --seed 4 --encoder-start 20000 >"$work/feed-a2.txt" || fails=$((fails + 1))
check "inspection went on without the database" grep -q ", 0 refused" "$work/feed-a2.txt"
"$ctl" status --server "$addr_a" >"$work/status-down.txt"
check "status says the database is unreachable" grep -q "forwarding as srv-a .*unreachable" "$work/status-down.txt"
check "and warns with the records waiting" grep -qE "warning: forwarding to PostgreSQL .*unreachable: [1-9][0-9]* records" "$work/status-down.txt"
sleep 25
start_pg || { echo "FAIL PostgreSQL did not restart"; exit 1; }
check "server a drained its lag" caught_up "$addr_a" 90

# Server b killed with SIGKILL in the middle of a forwarding transaction: the fillets table
# is held locked, so its batch has written the chain's links and waits to write the fillets.
psql "$db" -c "BEGIN; LOCK TABLE fillets IN ACCESS EXCLUSIVE MODE; SELECT pg_sleep(120); COMMIT;" \
  >/dev/null 2>&1 &
locker=$!
"$ctl" feed --server "$addr_b" --config "$work/feed-b.yaml" --simulate --lanes 2 --fillets 3 --seed 5 >"$work/feed-b.txt" || fails=$((fails + 1))
waiting() { [ "$(q "SELECT count(*) FROM pg_stat_activity WHERE wait_event_type = 'Lock' AND query LIKE 'INSERT INTO fillets%'")" -ge 1 ]; }
for _ in $(seq 100); do waiting && break; sleep 0.2; done
check "server b's forwarder waits inside its transaction" waiting
kill -9 "$pid_b"
wait "$pid_b" 2>/dev/null
q "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE query LIKE '%pg_sleep(120)%' AND pid <> pg_backend_pid()" >/dev/null
wait "$locker" 2>/dev/null
start_server b 2
check "server b caught up after SIGKILL" caught_up "$addr_b" 90

# Exactly once: PostgreSQL holds each server's whole chain, every link once.
for s in a b; do
  eval "addr=\$addr_$s"
  local_links=$("$ctl" audit verify --data "$work/data-$s" | sed -nE 's/chain verified: ([0-9]+) links.*/\1/p')
  pg_links=$(q "SELECT count(*) FROM ledger WHERE server_id = 'srv-$s'")
  distinct=$(q "SELECT count(DISTINCT seq) FROM ledger WHERE server_id = 'srv-$s'")
  check "srv-$s: PostgreSQL holds the $local_links links of its store once ($pg_links, $distinct distinct)" \
    test -n "$local_links" -a "$pg_links" = "$local_links" -a "$distinct" = "$local_links"
  local_fillets=$("$ctl" fillets --server "$addr" --limit 1000 | grep -c "^lane ")
  pg_fillets=$(q "SELECT count(*) FROM fillets WHERE server_id = 'srv-$s'")
  check "srv-$s: its $local_fillets fillets are there ($pg_fillets)" test "$pg_fillets" = "$local_fillets"
done
"$ctl" audit verify --db "$db" >"$work/verify.txt"
check "audit verify --db: both chains verify" test "$(grep -c "chain verified" "$work/verify.txt")" -eq 2
# Retention by whole days: today's records stay.
"$ctl" db prune --db "$db" --keep-days 1 >"$work/prune.txt" || fails=$((fails + 1))
check "db prune keeps today ($(head -1 "$work/prune.txt"))" grep -q "^dropped 0 partitions" "$work/prune.txt"
"$ctl" db prune --db "$db" >/dev/null 2>"$work/prune-err.txt"
check "db prune without a cutoff is refused by name" grep -q "needs one of --keep-days" "$work/prune-err.txt"

# The fleet view over the same database, from server a's plant file.
"$srv" --fleet --config "$work/plant.yaml" --http 127.0.0.1:0 >"$work/fleet.log" 2>&1 &
pids+=($!)
for _ in $(seq 100); do grep -q "fleet view of plant" "$work/fleet.log" && break; sleep 0.1; done
fleet=$(sed -nE 's|.*, at (http://[0-9.]+:[0-9]+)/.*|\1|p' "$work/fleet.log")
check "the fleet view serves" test -n "$fleet"
# Both servers have written their rows since b restarted (its dashboard's new address).
rows_current() { [ "$(q "SELECT count(*) FROM servers WHERE health <> '' AND http IN ('$web_a', '$web_b')")" = 2 ]; }
for _ in $(seq 100); do rows_current && break; sleep 0.2; done
check "both servers describe themselves in PostgreSQL" rows_current
/usr/bin/python3 - "$fleet" "srv-a=$web_a" "srv-b=$web_b" >"$work/fleet-compare.txt" 2>&1 <<'PY'
# The fleet's answers against the union of the servers' own answers.
import json, sys, urllib.request, urllib.error
fleet, servers = sys.argv[1], dict(a.split("=", 1) for a in sys.argv[2:])
def get(url):
    with urllib.request.urlopen(url, timeout=30) as r:
        return r.read()
def js(url): return json.loads(get(url))
def key(f): return (f["uid"], f["lane"], f["lane_fillet"], f["decision"], f["decided_ns"],
                    len(f["fragments"]), tuple(sorted(f["images"])))
fails = 0
def check(name, ok):
    global fails
    print(("ok   " if ok else "FAIL ") + name)
    fails += not ok
mine = {(s, key(f)) for s, w in servers.items() for f in js(w + "/api/fillets?limit=10000")["fillets"]}
theirs = {(f["server"], key(f)) for f in js(fleet + "/api/fillets?limit=10000")["fillets"]}
check(f"fleet fillets = the union of the servers' ({len(theirs)} and {len(mine)})", mine == theirs and len(mine) > 0)
# Paged in threes, in (decided_ns, server, uid) order, with the fleet's cursor.
paged, after = [], "0"
while True:
    page = js(f"{fleet}/api/fillets?limit=3&after={after}")
    paged += [(f["server"], f["uid"]) for f in page["fillets"]]
    if len(page["fillets"]) < 3: break
    after = page["next_after"]
check(f"pages of 3 give every fillet once ({len(paged)})", sorted(paged) == sorted((s, k[0]) for s, k in mine) and len(set(paged)) == len(paged))
rejects = {(f["server"], f["uid"]) for f in js(fleet + "/api/fillets?decision=reject&server=srv-b&limit=10000")["fillets"]}
check("a search by server and decision", rejects == {(s, k[0]) for s, k in mine if s == "srv-b" and k[3] == "reject"})
csv = get(fleet + "/api/fillets.csv").decode().splitlines()
check(f"CSV export: a header and {len(mine)} rows with their server", len(csv) == len(mine) + 1 and csv[0].startswith("server,") and all(r.split(",")[0] in servers for r in csv[1:]))
lanes_own = {(s, l["lane"]) for s, w in servers.items() for l in js(w + "/api/lanes")}
lanes_fleet = {(l["server"], l["lane"]) for l in js(fleet + "/api/lanes")}
check(f"fleet lanes = the servers' lanes ({sorted(lanes_fleet)})", lanes_own == lanes_fleet and len(lanes_own) == 4)
up = {s["server"]: s["up"] for s in js(fleet + "/api/servers")}
check(f"both servers up, with their lag ({up})", up == {"srv-a": True, "srv-b": True})
audit_own = sum(len(js(w + "/api/audit?limit=100000")) for w in servers.values())
check(f"fleet audit holds every server's entries ({audit_own})", len(js(fleet + "/api/audit?limit=100000")) == audit_own)
cal_own = sorted((s, v["lane"], v["id"], v["active"]) for s, w in servers.items() for v in js(w + "/api/calibrations")["versions"])
cal_fleet = sorted((v["server"], v["lane"], v["id"], v["active"]) for v in js(fleet + "/api/calibrations")["versions"] if v["kind"] == "calibration")
check(f"calibration versions: the servers' ({cal_own})", cal_own == cal_fleet and len(cal_own) > 0)
events = [e["what"] for e in js(fleet + "/api/calibrations")["events"] if e["server"] == "srv-a"]
check(f"and who uploaded and activated them ({events})", "calibration.upload" in events and any(e.startswith("calibration.activate") for e in events))
# An image through the server that keeps it: the same bytes.
held = [(s, k[0]) for s, k in mine if "overlay" in k[6]]
if held:
    s, uid = sorted(held)[0]
    own = get(f"{servers[s]}/api/fillets/{uid}/images/overlay")
    via = get(f"{fleet}/api/fillets/{s}/{uid}/images/overlay")
    check(f"{s}'s overlay of fillet {uid} through the fleet: the same {len(own)} bytes", own == via)
    one = js(f"{fleet}/api/fillets/{s}/{uid}")
    check("a fillet says which server keeps its images", one["kept_by"]["server"] == s)
else:
    check("a fillet with an image to fetch", False)
metrics = get(fleet + "/metrics").decode()
check("fleet /metrics: each server up", 'rangex_fleet_server_up{server="srv-a"} 1' in metrics and 'rangex_fleet_server_up{server="srv-b"} 1' in metrics)
print(json.dumps(sorted(held)[:1]))
sys.exit(1 if fails else 0)
PY
check "the fleet view answers as the servers do (fleet-compare below)" test $? -eq 0
cat "$work/fleet-compare.txt"
# And in a browser, as QA will use it.
/usr/bin/python3 "$(dirname "$0")/python/fleet_browser.py" "$fleet" "${RANGEX_SCREENSHOTS:-$work/shots}" \
  >"$work/fleet-browser.txt" 2>&1
check "the fleet's dashboard in a browser (fleet-browser below)" test $? -eq 0
cat "$work/fleet-browser.txt"
# Server b gone: its image is not, and the fleet names the server that cannot be reached.
image_b=$(q "SELECT fillet_uid FROM images WHERE server_id = 'srv-b' AND kind = 'overlay' ORDER BY fillet_uid LIMIT 1")
kill -9 "$pid_b"
wait "$pid_b" 2>/dev/null
code=$(/usr/bin/python3 -c '
import sys, urllib.request, urllib.error
try:
    urllib.request.urlopen(sys.argv[1], timeout=30); print(200)
except urllib.error.HTTPError as e:
    open(sys.argv[2], "wb").write(e.read()); print(e.code)' \
  "$fleet/api/fillets/srv-b/$image_b/images/overlay" "$work/unreachable.json")
check "an image of a server that is down: 502 ($code)" test "$code" = 502
check "naming the server that keeps it" grep -q "server srv-b at http://.* is unreachable" "$work/unreachable.json"

# srv-b's hardware failed: the plant file now gives lane 2 to srv-a, which restarts with it.
# The lane keeps one history: its fillet numbers go on from srv-b's last, and srv-a's chain
# names the link of srv-b's it continues from.
plant_file "$work/plant-moved.yaml" srv-a
kill -TERM "$pid_a"
wait "$pid_a" 2>/dev/null
start_server a 2 "$work/plant-moved.yaml"
check "srv-a runs lane 2 now" grep -q "server srv-a runs lanes 0, 1, 2" "$work/rangexd-a.log"
sed -e '/^  - id: [013]$/d' "$base" >"$work/feed-2.yaml"
"$ctl" feed --server "$addr_a" --config "$work/feed-2.yaml" --simulate --lanes 1 --fillets 2 --seed 6 \
  --encoder-start 200000 >"$work/feed-moved.txt" || fails=$((fails + 1))
check "srv-a caught up with lane 2" caught_up "$addr_a" 60
last_b=$(q "SELECT max(lane_fillet) FROM fillets WHERE server_id = 'srv-b' AND lane = 2")
adopted=$(q "SELECT detail FROM audit WHERE server_id = 'srv-a' AND what = 'lane.adopted'")
check "srv-a's chain: lane 2 adopted after srv-b's fillet $last_b ($adopted)" \
  grep -qE "^lane 2 continues from server srv-b: its fillet $last_b \(uid [0-9]+, link [0-9]+ [0-9a-f]{64}\)" <<<"$adopted"
history=$(q "SELECT string_agg(server_id || ':' || lane_fillet, ' ' ORDER BY decided_ns) FROM fillets WHERE lane = 2")
first_a=$(q "SELECT min(lane_fillet) FROM fillets WHERE server_id = 'srv-a' AND lane = 2")
check "lane 2's numbers go on across servers ($history)" test -n "$first_a" -a "$first_a" = "$((last_b + 1))"
check "no lane 2 number twice" test "$(q "SELECT count(*) - count(DISTINCT lane_fillet) FROM fillets WHERE lane = 2")" = 0

# A decision changed behind rangex's back is named, on its server only.
q "UPDATE fillets SET decision = 'pass' WHERE server_id = 'srv-b' AND uid = (SELECT min(uid) FROM fillets WHERE server_id = 'srv-b' AND decision = 'reject')" >/dev/null
"$ctl" audit verify --db "$db" >"$work/verify2.txt"
check "audit verify --db fails (exit 1)" test $? -eq 1
check "names srv-b's first broken link" grep -q "server srv-b: chain BROKEN at link [0-9]" "$work/verify2.txt"
check "srv-a's chain still verifies" grep -q "server srv-a: chain verified" "$work/verify2.txt"

[ "$fails" -eq 0 ] || { echo "$fails checks failed"; for f in "$work"/rangexd-*.log; do tail -n 20 "$f"; done; exit 1; }
echo "all checks passed"
