#!/usr/bin/env python3
"""Crash and stop consistency: rangexd killed with SIGKILL (or stopped with SIGTERM and SIGHUP)
at random moments while a simulated plant streams into it, restarted each time on the same store and
port. A stop refuses new lines and hands them back with the fillets still coming in; the
feeder sends them to the next server, so a stop, like a crash, loses nothing.

First a reference run with no kill, on a store of its own. Then, for each seed, a crash run: a calibration
is activated on lane 1, the feeder (`rangexctl feed`, which reconnects and resends what the
server has not made durable) streams the same plant, a subscriber (one `rangexctl watch`
for the whole run: it connects again after each kill) records every decision it is shown, and
rangexd is killed KILLS times at random points and restarted.

Checks:
- every decision the subscriber saw is in the store, as it was sent, and it saw every stored
  decision exactly once, in the store's order (what was decided while it was away it takes
  from the store);
- the record chain verifies;
- the active calibration is the one activated;
- no fillet was decided twice (no two records of a lane share an encoder count);
- nothing was lost: the store holds the reference run's fillets, count ranges and decisions;
- the feeder resent what the server had not made durable (lines the server had are answered
  DUPLICATE; the checks above show none was decided again).

With PLC (the word), each crash run releases to that simulated PLC over
Modbus TCP (plant.yaml plc), and:
- no fillet reached the PLC twice across the kills;
- every release the PLC took is a stored decision, with its decision (a pass may be late);
- the PLC was told the lanes stopped at the end.
A pass decided just before a kill and not yet sent never reaches the PLC: the PLC diverts it.

Every wait is bounded.

usage: crash_test.py RANGEXD RANGEXCTL [KILLS] [SEED[,SEED...]] [KILL|TERM] [PLC]
"""
import os
import random
import re
import signal
import socket
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time

from checks import check, fail

rangexd, rangexctl = sys.argv[1:3]
kills = int(sys.argv[3]) if len(sys.argv) > 3 else 3
seeds = [int(x) for x in sys.argv[4].split(",")] if len(sys.argv) > 4 else [14]
how = sys.argv[5] if len(sys.argv) > 5 else "KILL"
with_plc = len(sys.argv) > 6 and sys.argv[6] == "PLC"
if how not in ("KILL", "TERM"):
    fail("the last argument is KILL or TERM (got %s)" % how)
signal.alarm(150 + 200 * len(seeds))  # the whole test, whatever hangs
tmp = tempfile.mkdtemp(prefix="rangex-crash-")
FEED = ["--simulate", "--lanes", "2", "--fillets", "8", "--seed", "5"]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    def __init__(self, data, port):
        self.data, self.addr, self.proc, self.log = data, "127.0.0.1:%d" % port, None, []
        self.config = None  # a plant.yaml of its own (with a PLC); None: RANGEX_CONFIG

    def start(self):
        err = open(os.path.join(tmp, "rangexd.log"), "a")
        extra = ["--config", self.config] if self.config else []
        self.proc = subprocess.Popen([rangexd, "--listen", self.addr, "--http", "off",
                                      "--backend", "cpu", "--data", self.data] + extra,
                                     stdout=subprocess.DEVNULL, stderr=err)
        end = time.time() + 30
        while time.time() < end:
            if self.proc.poll() is not None:
                fail("rangexd exited with %d at start (see %s)" % (self.proc.returncode, err.name))
            if ctl("status", "--server", self.addr, check=False).returncode == 0:
                return
            time.sleep(0.1)
        fail("rangexd did not serve within 30 s")

    def kill(self):
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=30)

    def interrupt(self, k):
        """SIGKILL, or a stop that must end cleanly: SIGTERM, and every second one SIGHUP (a
        terminal that closed; it once ended rangexd undrained, exit 129)."""
        if how == "KILL":
            return self.kill()
        sig = signal.SIGHUP if k % 2 else signal.SIGTERM
        self.proc.send_signal(sig)
        rc = self.proc.wait(timeout=90)
        if rc != 0:
            fail("rangexd stopped by %s with %d (see %s)"
                 % (sig.name, rc, os.path.join(tmp, "rangexd.log")))

    def stop(self):
        self.proc.send_signal(signal.SIGTERM)
        if self.proc.wait(timeout=90) != 0:
            fail("rangexd stopped with %d" % self.proc.returncode)


def ctl(*args, check=True, timeout=60):
    r = subprocess.run([rangexctl] + list(args), capture_output=True, text=True, timeout=timeout)
    if check and r.returncode != 0:
        fail("rangexctl %s: %s" % (" ".join(args), r.stderr.strip()))
    return r


def fillets(data):
    db = sqlite3.connect(os.path.join(data, "rangex.sqlite"))
    return db.execute("SELECT uid, lane, first_encoder, rows, decision FROM fillets "
                      "ORDER BY uid").fetchall()


def settle(server):
    """Waits until the server has processed everything it accepted and nothing changes."""
    last, end = None, time.time() + 60
    while time.time() < end:
        out = ctl("status", "--server", server.addr).stdout
        m = re.search(r"lines: (\d+) received, (\d+) accepted, (\d+) processed", out)
        now = m.groups() if m else None
        if now and now[1] == now[2] and now == last:
            return
        last = now
        time.sleep(0.5)
    fail("the server did not settle within 60 s")


# --- the reference: the same plant, no kill ------------------------------------------------
ref = Server(os.path.join(tmp, "reference"), free_port())
ref.start()
out = ctl("feed", "--server", ref.addr, *FEED, timeout=180).stdout
check(" 0 refused" in out, "reference feed: every line accepted (%s)" % out.strip().splitlines()[0])
settle(ref)
ref.stop()
reference = fillets(ref.data)
check(len(reference) >= 8, "the reference run decided %d fillets" % len(reference))

# --- the crash runs --------------------------------------------------------------------------
class Plc:
    """`rangexctl plc-sim`: its port, then what it took when it is stopped."""

    def __init__(self, name):
        portfile = os.path.join(tmp, name + ".port")
        self.proc = subprocess.Popen([rangexctl, "plc-sim", "--port-file", portfile, "--list",
                                      "--every", "3600"], stdout=subprocess.PIPE, text=True)
        end = time.time() + 30
        while not os.path.exists(portfile):
            if time.time() > end or self.proc.poll() is not None:
                fail("the simulated PLC did not start")
            time.sleep(0.05)
        self.port = int(open(portfile).read())

    def config(self, name):
        """RANGEX_CONFIG with this PLC."""
        path = os.path.join(tmp, name + "-plant.yaml")
        with open(os.environ["RANGEX_CONFIG"]) as f, open(path, "w") as out:
            out.write(f.read() + "\nplc:\n  address: 127.0.0.1:%d\n" % self.port)
        return path

    def finish(self):
        self.proc.send_signal(signal.SIGTERM)
        out, _ = self.proc.communicate(timeout=30)
        releases = [(int(f[1]), int(f[2]), int(f[3]), f[4], int(f[5]))
                    for f in (l.split() for l in out.splitlines()) if f[0] == "release"]
        states = [(int(f[1]), f[2], int(f[3]))
                  for f in (l.split() for l in out.splitlines()) if f[0] == "state"]
        return releases, states


def check_releases(plc, stored):
    """What the simulated PLC took against what the store decided."""
    releases, states = plc.finish()
    keys = [(r[0], r[1]) for r in releases]
    twice = sorted({k for k in keys if keys.count(k) > 1})
    check(releases and not twice, "no fillet reached the PLC twice across the kills "
          "(%d releases; twice: %s)" % (len(releases), twice[:5]))
    by_key = {(f[1], f[2] & 0xffffffff): f[4] for f in stored}
    codes = {"pass": ("pass", "late"), "reject": ("reject",), "not_inspected": ("not_inspected",)}
    wrong = [r for r in releases if r[3] not in codes.get(by_key.get((r[0], r[1])), ())]
    check(not wrong, "every release is a stored decision, as decided (%s)" % wrong[:5])
    passes = [k for k, d in by_key.items() if d == "pass"]
    sent = set(keys)
    print("the PLC took %d releases; %d of %d passes released (the rest, decided just before a "
          "kill, diverted); %d late" % (len(releases), sum(k in sent for k in passes),
                                         len(passes), sum(r[3] == "late" for r in releases)))
    stopped = [s for s in states if s[0] in (0, 1) and s[1:] != ("stopped", 4)]
    check(not stopped, "the PLC was told the lanes stopped (%s)" % stopped)


def crash_run(seed):
    rng = random.Random(seed)
    server = Server(os.path.join(tmp, "crash-%d" % seed), free_port())
    plc = Plc("plc-%d" % seed) if with_plc else None
    if plc:
        server.config = plc.config("crash-%d" % seed)
    server.start()
    cal = os.path.join(tmp, "crash-cal.yaml")
    with open(cal, "w") as f:  # the shipped geometry under a new id: decisions comparable
        f.write("laser_plane: {normal: [0, 1, 0], offset_mm: 0.0}\n")
    ctl("calib", "upload", "--server", server.addr, "--lane", "1", "--id", "crash-cal", "--file", cal)
    ctl("calib", "activate", "--server", server.addr, "--lane", "1", "--id", "crash-cal", "--force")

    # One watcher for the whole run: it reconnects after each kill and takes what was decided
    # while it was away from the store, so it must show every stored decision exactly once.
    seen = []
    watcher = subprocess.Popen([rangexctl, "watch", "--server", server.addr, "--reconnect-for",
                                "120"], stdout=subprocess.PIPE,
                               stderr=open(os.path.join(tmp, "watch-%d.log" % seed), "w"),
                               text=True)

    def watch():
        for line in watcher.stdout:
            m = re.match(r"lane (\d+) fillet (\d+)\s+uid (\d+)\s+(PASS|REJECT|NOT INSPECTED)", line)
            if m:
                seen.append((int(m.group(3)), int(m.group(1)), m.group(4)))

    reader = threading.Thread(target=watch, daemon=True)
    reader.start()
    end = time.time() + 30
    while not re.search(r"; [1-9]\d* subscribers", ctl("status", "--server", server.addr).stdout):
        if time.time() > end or watcher.poll() is not None:
            fail("`rangexctl watch` did not subscribe within 30 s")
        time.sleep(0.1)
    # Paced (about 13 s of lines), so that the kills fall mid-stream on a fast machine too.
    feeder = subprocess.Popen([rangexctl, "feed", "--server", server.addr, "--reconnect-for", "90",
                               "--rate", "300"] + FEED,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # The kills start once lines are flowing (the feeder renders its plant first).
    end = time.time() + 60
    while time.time() < end:
        m = re.search(r"lines: (\d+) received", ctl("status", "--server", server.addr).stdout)
        if m and int(m.group(1)) > 0:
            break
        time.sleep(0.1)
    else:
        fail("no line reached rangexd within 60 s")
    done_kills = 0
    for k in range(kills):
        time.sleep(rng.uniform(0.8, 2.5))
        if feeder.poll() is not None:
            break
        server.interrupt(k)
        done_kills += 1
        print("%s rangexd (%d) after %d decisions seen"
              % ("killed" if how == "KILL" else "stopped", done_kills, len(seen)), flush=True)
        time.sleep(rng.uniform(0.0, 0.5))
        server.start()
    try:
        feed_out, feed_err = feeder.communicate(timeout=240)
    except subprocess.TimeoutExpired:
        feeder.kill()
        fail("the feeder did not finish within 240 s")
    check(done_kills >= 2, "rangexd was %s %d times while the plant streamed"
          % ("killed" if how == "KILL" else "stopped", done_kills))
    handed = re.search(r"(\d+) refusals handed lines back", feed_out)
    print("the feeder had %s lines handed back" % (handed.group(1) if handed else "no"))
    check(feeder.returncode == 0 and " 0 refused" in feed_out,
          "the feeder delivered every line through the kills (%s)" % feed_out.strip().replace("\n", "; "))
    m = re.search(r"(\d+) reconnects, (\d+) lines resent \((\d+) the server already had\)", feed_out)
    # Lines the server had made durable after the last acknowledgement the feeder read are
    # answered DUPLICATE (the no-second-decision checks below cover them); the rest it rebuilds.
    check(m and int(m.group(1)) >= 1,
          "the feeder reconnected after the kills and resent what was not durable (%s)"
          % (m.group(0) if m else feed_out))
    settle(server)
    stored = fillets(server.data)
    end = time.time() + 30
    while len(seen) < len(stored) and time.time() < end and watcher.poll() is None:
        time.sleep(0.1)
    time.sleep(0.5)  # a decision shown twice would come now
    watcher.kill()
    watcher.wait()
    reader.join(timeout=10)
    server.stop()

    by_uid = {f[0]: f for f in stored}
    missing = [s for s in seen if s[0] not in by_uid]
    check(len(seen) > 0 and not missing, "every one of the %d decisions the watcher saw is in the "
          "store (missing: %s)" % (len(seen), missing[:5]))
    uids = [s[0] for s in seen]
    unseen = sorted(set(by_uid) - set(uids))
    twice = sorted({u for u in uids if uids.count(u) > 1})
    check(not unseen and not twice and uids == sorted(uids),
          "the watcher, one `rangexctl watch` through every %s, showed each of the %d stored "
          "decisions once, in order (not shown: %s; twice: %s)"
          % ("kill" if how == "KILL" else "stop", len(stored), unseen[:5], twice[:5]))
    names = {"PASS": "pass", "REJECT": "reject", "NOT INSPECTED": "not_inspected"}
    changed = [s for s in seen if by_uid[s[0]][1] != s[1] or by_uid[s[0]][4] != names[s[2]]]
    check(not changed, "each as it was sent (%s)" % changed[:5])
    r = ctl("audit", "verify", "--data", server.data, check=False)
    check(r.returncode == 0, "the record chain verifies (%s)" % r.stdout.strip())
    db = sqlite3.connect(os.path.join(server.data, "rangex.sqlite"))
    active = db.execute("SELECT lane, id FROM calibrations WHERE active = 1").fetchall()
    check(active == [(1, "crash-cal")], "the active calibration is the one activated (%s)" % active)
    overlaps = []
    for lane in (0, 1):
        spans = sorted((f[2], f[2] + f[3] - 1) for f in stored if f[1] == lane)
        overlaps += [(lane, a, b) for a, b in zip(spans, spans[1:]) if b[0] <= a[1]]
    check(not overlaps, "no fillet was decided twice (%s)" % overlaps[:5])
    want = sorted((f[1], f[2], f[3], f[4]) for f in reference)
    got = sorted((f[1], f[2], f[3], f[4]) for f in stored)
    lost = [f for f in want if f not in got]
    extra = [f for f in got if f not in want]
    check(not lost and not extra,
          "the store holds the reference run's %d fillets with their decisions (lost %s, other %s)"
          % (len(want), lost[:4], extra[:4]))
    if plc:
        check_releases(plc, stored)
    print("crash_test: all checks passed (seed %d, %d %s, %d decisions seen)"
          % (seed, done_kills, "kills" if how == "KILL" else "stops", len(seen)), flush=True)


for seed in seeds:
    crash_run(seed)
