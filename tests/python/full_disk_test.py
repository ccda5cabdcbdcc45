#!/usr/bin/env python3
"""A store volume that fills while a plant streams and stays full past exit_after_s.

rangexd runs with an injected full disk (tests/fault/enospc_preload.cpp: every write to a
file fails with ENOSPC while a flag file exists). The disk fills mid-feed; then:
- the store's failure names a full disk;
- admission hands lines back (STORE_UNAVAILABLE) instead of taking what it cannot keep;
- rangexd exits 3 after exit_after_s, and no image under its own name is half written;
- the feeder keeps every line not durable and waits;
- space is freed, rangexd restarts on the same store, the feeder sends its lines again and
  ends with every lane settled;
- the store then equals a run on a disk that never filled: the same fillets and decisions,
  every reject's images whole and registered, and the record chain verifies.
Last, a server that never comes back: the feeder gives up after --reconnect-for and names
the counts whose outcomes are not known to be stored.

Every wait is bounded.

usage: full_disk_test.py RANGEXD RANGEXCTL ENOSPC_PRELOAD PLANT_YAML
"""
import glob
import os
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

rangexd, rangexctl, preload, config = sys.argv[1:5]
signal.alarm(540)  # the whole test, whatever hangs
tmp = tempfile.mkdtemp(prefix="rangex-full-")
flag = os.path.join(tmp, "disk-full")
plant = os.path.join(tmp, "plant.yaml")
with open(config) as src:
    text, n = re.subn(r"(?m)^(\s+exit_after_s:)\s*[0-9.]+", r"\1 3", src.read())
if n != 1:
    fail("the plant configuration has no server.exit_after_s to shorten")
with open(plant, "w") as dst:
    dst.write(text)
ENV = dict(os.environ, LD_PRELOAD=os.path.abspath(preload), RANGEX_DISK_FULL_FLAG=flag,
           RANGEX_CONFIG=plant)
CTL_ENV = dict(os.environ, RANGEX_CONFIG=plant)  # the clients write nothing to the store
FEED = ["--simulate", "--lanes", "2", "--fillets", "8", "--seed", "5"]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def ctl(*args, check_rc=True, timeout=60):
    r = subprocess.run([rangexctl] + list(args), capture_output=True, text=True,
                       timeout=timeout, env=CTL_ENV)
    if check_rc and r.returncode != 0:
        fail("rangexctl %s: %s" % (" ".join(args), r.stderr.strip()))
    return r


class Server:
    def __init__(self, data):
        self.data, self.addr, self.proc, self.log = data, "127.0.0.1:%d" % free_port(), None, []

    def start(self):
        self.proc = subprocess.Popen([rangexd, "--config", plant, "--listen", self.addr,
                                      "--http", "off", "--backend", "cpu", "--data", self.data],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                     env=ENV)
        threading.Thread(target=lambda p=self.proc: self.log.extend(p.stderr), daemon=True).start()
        end = time.time() + 30
        while time.time() < end:
            if self.proc.poll() is not None:
                fail("rangexd exited with %d at start: %s" % (self.proc.returncode,
                                                              "".join(self.log[-5:])))
            if ctl("status", "--server", self.addr, check_rc=False).returncode == 0:
                return
            time.sleep(0.1)
        fail("rangexd did not serve within 30 s")

    def stop(self):
        self.proc.send_signal(signal.SIGTERM)
        if self.proc.wait(timeout=90) != 0:
            fail("rangexd stopped with %d: %s" % (self.proc.returncode, "".join(self.log[-5:])))


def fillets(data):
    db = sqlite3.connect(os.path.join(data, "rangex.sqlite"))
    return db.execute("SELECT uid, lane, first_encoder, rows, decision FROM fillets "
                      "ORDER BY uid").fetchall()


def stored_fillets():
    m = re.search(r"fillets: (\d+)", ctl("status", "--server", server.addr).stdout)
    return int(m.group(1)) if m else 0


# --- the reference: the same plant on a disk that never fills ------------------------------
ref = Server(os.path.join(tmp, "reference"))
ref.start()
out = ctl("feed", "--server", ref.addr, *FEED, timeout=240).stdout
check(" 0 refused" in out and "every lane settled" in out,
      "reference feed: every line accepted and settled (%s)" % out.strip().replace("\n", "; "))
ref.stop()
reference = fillets(ref.data)
check(len(reference) >= 8, "the reference run decided %d fillets" % len(reference))

# --- the disk fills mid-feed and stays full past exit_after_s -------------------------------
server = Server(os.path.join(tmp, "full"))
server.start()
feeder = subprocess.Popen([rangexctl, "feed", "--server", server.addr, "--rate", "300",
                           "--reconnect-for", "240", "--settle-for", "240"] + FEED,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=CTL_ENV)
end = time.time() + 90
while time.time() < end and stored_fillets() < 3:
    time.sleep(0.2)
check(stored_fillets() >= 3, "decisions are stored before the disk fills")
open(flag, "w").close()
print("the store volume is full", flush=True)
try:
    rc = server.proc.wait(timeout=120)
except subprocess.TimeoutExpired:
    fail("rangexd kept running for 120 s on a full disk: %s" % "".join(server.log[-5:]))
log = "".join(server.log)
check(rc == 3, "rangexd exits 3 once the disk has been full for exit_after_s (exit %d)" % rc)
check("disk full" in log and "cannot rollback" not in log,
      "the reason it gives is a full disk (%s)"
      % [l.strip() for l in server.log if "store" in l][:3])
check(feeder.poll() is None, "the feeder waits with the lines that are not durable")
# rangexd exits at once (a worker may be stalled): a write it cut off leaves its .part, never
# an image under its own name that is not whole. The restart clears what was staged.
cut = [p for p in glob.glob(os.path.join(server.data, "**", "*.png"), recursive=True)
       if not open(p, "rb").read().endswith(b"IEND\xaeB`\x82")]
check(not cut, "no image under its own name is half written (%s)" % cut[:3])

os.remove(flag)
print("space freed; rangexd restarts", flush=True)
server.log.clear()
server.start()
try:
    feed_out, feed_err = feeder.communicate(timeout=300)
except subprocess.TimeoutExpired:
    feeder.kill()
    fail("the feeder did not finish within 300 s of the restart")
summary = feed_out.strip().replace("\n", "; ")
check(feeder.returncode == 0 and " 0 refused" in feed_out and "every lane settled" in feed_out,
      "the feeder delivered every line and every lane settled (exit %d: %s)"
      % (feeder.returncode, summary))
check(re.search(r"[1-9]\d* refusals handed lines back", feed_out) is not None,
      "admission handed lines back while the store could not write (%s)" % summary)
server.stop()

stored = fillets(server.data)
want = sorted(f[1:] for f in reference)
got = sorted(f[1:] for f in stored)
lost = [f for f in want if f not in got]
extra = [f for f in got if f not in want]
check(not lost and not extra,
      "the store holds the reference run's %d fillets with their decisions (lost %s, other %s)"
      % (len(want), lost[:4], extra[:4]))
db = sqlite3.connect(os.path.join(server.data, "rangex.sqlite"))
missing = []
for uid, lane, first, rows, decision in stored:
    if decision == "pass":
        continue
    paths = [p for (p,) in db.execute("SELECT path FROM images WHERE fillet_uid = ?", (uid,))]
    if len(paths) < 4 or not all(os.path.getsize(p) > 0 for p in paths):
        missing.append((uid, decision, len(paths)))
check(not missing, "every reject's images are written whole and registered (%s)" % missing[:4])
partial = glob.glob(os.path.join(server.data, "**", "*.part"), recursive=True)
check(not partial, "no partial image is left (%s)" % partial[:3])
r = ctl("audit", "verify", "--data", server.data, check_rc=False)
check(r.returncode == 0, "the record chain verifies (%s)" % r.stdout.strip())

# --- a server that does not come back -------------------------------------------------------
gone = Server(os.path.join(tmp, "gone"))
gone.start()
feeder = subprocess.Popen([rangexctl, "feed", "--server", gone.addr, "--rate", "300",
                           "--reconnect-for", "3", "--settle-for", "5"] + FEED,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=CTL_ENV)
end = time.time() + 90
while time.time() < end:
    m = re.search(r"lines: (\d+) received", ctl("status", "--server", gone.addr).stdout)
    if m and int(m.group(1)) > 0:
        break
    time.sleep(0.1)
gone.proc.send_signal(signal.SIGKILL)
gone.proc.wait(timeout=30)
try:
    out, err = feeder.communicate(timeout=120)
except subprocess.TimeoutExpired:
    feeder.kill()
    fail("the feeder still waited 120 s after its server was gone for good")
check(feeder.returncode != 0 and re.search(r"NOT SETTLED: lane 0 counts -?\d+\.\.-?\d+", out),
      "with its server gone for good the feeder gives up and names the counts not settled "
      "(exit %d: %s)" % (feeder.returncode, (out + err).strip().replace("\n", "; ")[-400:]))
print("full_disk_test: all checks passed")
