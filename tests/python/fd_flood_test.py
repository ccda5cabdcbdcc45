#!/usr/bin/env python3
"""Idle connections do not lock rangexd's clients out, and where they near its limit on open
files, rangexd says so.

rangexd starts with the soft open-file limit most services get (1024). A client opens 1,100
connections to its gRPC port, each sending HTTP/2's preface and nothing more, and holds
them. `rangexctl status` must still answer, and so must the dashboard. With the soft limit
as it was given, every gRPC client got "Deadline Exceeded" (rangexd: "Too many open files").

Then a rangexd whose hard limit is 1,300 (it cannot raise it) gets the same 1,100: its
statistics must count them and warn that it is near its limit (gRPC 1.51 bounds no count of
connections; at the limit no new gRPC client gets in), and the warning must go once they
close.

Skipped (exit 77) where the hard limit leaves no room for the test: rangexd needs more than
1,100 files and so does this script.

usage: fd_flood_test.py RANGEXD RANGEXCTL PLANT.yaml
"""
import os
import re
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

from checks import check, fail, free_port, terminate

rangexd, rangexctl, plant = sys.argv[1:4]
FLOOD = 1100
TIGHT = 1300  # the second server's hard limit: the flood is 85 % of it
signal.alarm(240)  # the whole test, whatever hangs

soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
room = hard if hard != resource.RLIM_INFINITY else 1 << 20
if room < 2 * FLOOD + 200:
    print("SKIP: the hard open-file limit (%d) leaves no room for %d connections on each side"
          % (room, FLOOD))
    sys.exit(77)
resource.setrlimit(resource.RLIMIT_NOFILE, (min(room, 4096), hard))


def as_a_service():  # the soft limit a service starts with; the hard one left as it is
    resource.setrlimit(resource.RLIMIT_NOFILE, (1024, hard))


def with_a_tight_limit():  # a hard limit rangexd cannot raise
    resource.setrlimit(resource.RLIMIT_NOFILE, (TIGHT, TIGHT))


tmp = tempfile.mkdtemp(prefix="rangex-fd-")
PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])


def start(name, limits):
    grpc, http = "127.0.0.1:%d" % free_port(), "127.0.0.1:%d" % free_port()
    out = open(os.path.join(tmp, name + ".log"), "w")
    proc = subprocess.Popen([rangexd, "--config", plant, "--listen", grpc, "--http", http,
                             "--backend", "cpu", "--data", os.path.join(tmp, name)],
                            stdout=out, stderr=subprocess.STDOUT, preexec_fn=limits)
    end = time.time() + 60
    while time.time() < end:
        if proc.poll() is not None:
            fail("rangexd exited with %d at start" % proc.returncode)
        try:
            with urllib.request.urlopen("http://%s/api/info" % http, timeout=5) as r:
                if r.status == 200:
                    return proc, grpc, http, out.name
        except OSError:
            pass
        time.sleep(0.2)
    fail("rangexd's dashboard did not answer within 60 s")


def flood(grpc):
    host, port = grpc.split(":")
    socks = []
    for i in range(FLOOD):
        s = socket.create_connection((host, int(port)), timeout=5)
        s.sendall(PREFACE)
        socks.append(s)
    time.sleep(1)
    return socks


def status(grpc):
    st = subprocess.run([rangexctl, "status", "--server", grpc], capture_output=True, text=True,
                        timeout=60)
    check(st.returncode == 0 and "SERVING" in st.stdout,
          "with %d idle connections open, `rangexctl status` answers (%s)"
          % (FLOOD, (st.stdout + st.stderr).strip().splitlines()[0:1]))
    m = re.search(r"^open files: (\d+) of (\d+)$", st.stdout, re.M)
    check(m, "and counts the open files")
    near = [l for l in st.stdout.splitlines() if l.startswith("warning: open files:")]
    return int(m.group(1)), int(m.group(2)), near


proc, socks = None, []
try:
    proc, grpc, http, log = start("raised", as_a_service)
    log = open(log).read()
    check("open files: up to" in log, "rangexd raised its soft open-file limit from 1024: "
          + next((l for l in log.splitlines() if "open files" in l), "(not said)"))
    socks = flood(grpc)
    held = len(os.listdir("/proc/%d/fd" % proc.pid))
    check(held > 1024, "rangexd holds %d files, past the 1024 it was started with" % held)
    n, limit, near = status(grpc)
    check(n >= FLOOD and limit > 1024 and (near == []) == (n < 0.8 * limit),
          "%d of %d, a warning only from 80 %% of the limit (%s)" % (n, limit, near))
    with urllib.request.urlopen("http://%s/api/lanes" % http, timeout=30) as r:
        check(r.status == 200, "and the dashboard's API answers")
    for s in socks:
        s.close()
    socks = []
    if not terminate(proc):
        fail("rangexd did not stop within 60 s of SIGTERM")

    proc, grpc, http, _ = start("tight", with_a_tight_limit)
    socks = flood(grpc)
    n, limit, near = status(grpc)
    check(limit == TIGHT and n >= FLOOD and near and "of the limit of %d" % TIGHT in near[0],
          "held to a hard limit of %d, rangexd warns with %d open: %s" % (TIGHT, n, near))
    with urllib.request.urlopen("http://%s/metrics" % http, timeout=30) as r:
        text = r.read().decode()
    m = re.search(r"^rangex_open_files (\d+)$", text, re.M)
    check(m and int(m.group(1)) >= FLOOD and "\nrangex_open_files_limit %d\n" % TIGHT in text,
          "/metrics counts them against the limit (%s)" % (m.group(0) if m else "no sample"))
    for s in socks:
        s.close()
    socks = []
    end = time.time() + 60
    while time.time() < end:
        n, _, near = status(grpc)
        if not near:
            break
        time.sleep(0.5)
    check(not near, "the warning goes once the connections close (%d open)" % n)
finally:
    for s in socks:
        s.close()
    if proc and proc.poll() is None and not terminate(proc):
        fail("rangexd did not stop within 60 s of SIGTERM")
shutil.rmtree(tmp, ignore_errors=True)
print("PASS")
