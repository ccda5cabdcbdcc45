#!/usr/bin/env bash
# Two rangexd forwarding to one real PostgreSQL (started here, initdb + pg_ctl), fed a
# simulated plant of 2 + 2 lanes: every record each server stores is in PostgreSQL exactly
# once, through a database stopped for 30 s mid-run and a rangexd killed with SIGKILL
# mid-forward; every server's chain verifies there, and an UPDATE behind rangex's back is
# named. Usage: plant_db_test.sh RANGEXCTL RANGEXD
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

# Two servers, two lanes each, one plant file each (the lanes' own section unchanged).
base="${RANGEX_CONFIG:-$(dirname "$0")/../config/plant.yaml}"
for s in a b; do
  sed -e "s|^  storage: .*|  storage: $work/data-$s\n  results_db: \"$db\"\n  server_id: srv-$s|" \
      -e '/^  - id: [23]$/d' "$base" >"$work/$s.yaml"
done
start_server() {  # start_server a|b: starts it, sets addr_a / addr_b
  local s=$1
  "$srv" --config "$work/$s.yaml" --listen 127.0.0.1:0 --http off >>"$work/rangexd-$s.log" 2>&1 &
  pids+=($!)
  eval "pid_$s=$!"
  for _ in $(seq 200); do
    [ "$(grep -c "listening on" "$work/rangexd-$s.log")" -ge "$2" ] && break
    sleep 0.1
  done
  eval "addr_$s=$(grep "listening on" "$work/rangexd-$s.log" | tail -1 | sed -nE 's/.*listening on ([0-9.]+:[0-9]+).*/\1/p')"
}
start_server a 1
start_server b 1
check "both servers listen" test -n "$addr_a" -a -n "$addr_b"

# Lag drains: `status` says caught up with the whole chain.
caught_up() {  # caught_up ADDR SECONDS
  for _ in $(seq $((${2} * 5))); do
    "$ctl" status --server "$1" 2>/dev/null | grep -q "caught up, 0 records" && return 0
    sleep 0.2
  done
  return 1
}
"$ctl" feed --server "$addr_a" --simulate --lanes 2 --fillets 2 --seed 3 >"$work/feed-a1.txt" || fails=$((fails + 1))
check "server a caught up" caught_up "$addr_a" 60

# PostgreSQL stopped for 30 s mid-run: inspection goes on, the lag grows, then drains.
pg_ctl -m fast -w stop >/dev/null
"$ctl" feed --server "$addr_a" --simulate --lanes 2 --fillets 2 --seed 4 --encoder-start 20000 >"$work/feed-a2.txt" || fails=$((fails + 1))
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
"$ctl" feed --server "$addr_b" --simulate --lanes 2 --fillets 3 --seed 5 >"$work/feed-b.txt" || fails=$((fails + 1))
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

# A decision changed behind rangex's back is named, on its server only.
q "UPDATE fillets SET decision = 'pass' WHERE server_id = 'srv-b' AND uid = (SELECT min(uid) FROM fillets WHERE server_id = 'srv-b' AND decision = 'reject')" >/dev/null
"$ctl" audit verify --db "$db" >"$work/verify2.txt"
check "audit verify --db fails (exit 1)" test $? -eq 1
check "names srv-b's first broken link" grep -q "server srv-b: chain BROKEN at link [0-9]" "$work/verify2.txt"
check "srv-a's chain still verifies" grep -q "server srv-a: chain verified" "$work/verify2.txt"

[ "$fails" -eq 0 ] || { echo "$fails checks failed"; for f in "$work"/rangexd-*.log; do tail -n 20 "$f"; done; exit 1; }
echo "all checks passed"
