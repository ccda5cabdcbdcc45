#!/usr/bin/env python3
"""Idle connections do not lock rangexd's clients out.

rangexd starts with the soft open-file limit most services get (1024). A client opens 1,100
connections to its gRPC port, each sending HTTP/2's preface and nothing more, and holds
them. `rangexctl status` must still answer, and so must the dashboard. With the soft limit
as it was given, every gRPC client got "Deadline Exceeded" (rangexd: "Too many open files").

Skipped (exit 77) where the hard limit leaves no room for the test: rangexd needs more than
1,100 files and so does this script.

usage: fd_flood_test.py RANGEXD RANGEXCTL PLANT.yaml
"""
import os
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


tmp = tempfile.mkdtemp(prefix="rangex-fd-")
grpc, http = "127.0.0.1:%d" % free_port(), "127.0.0.1:%d" % free_port()
out = open(os.path.join(tmp, "rangexd.log"), "w")
proc = subprocess.Popen([rangexd, "--config", plant, "--listen", grpc, "--http", http,
                         "--backend", "cpu", "--data", os.path.join(tmp, "data")],
                        stdout=out, stderr=subprocess.STDOUT, preexec_fn=as_a_service)
socks = []
try:
    end = time.time() + 60
    while time.time() < end:
        if proc.poll() is not None:
            fail("rangexd exited with %d at start" % proc.returncode)
        try:
            with urllib.request.urlopen("http://%s/api/info" % http, timeout=5) as r:
                if r.status == 200:
                    break
        except OSError:
            pass
        time.sleep(0.2)
    else:
        fail("rangexd's dashboard did not answer within 60 s")
    log = open(out.name).read()
    check("open files: up to" in log, "rangexd raised its soft open-file limit from 1024: "
          + next((l for l in log.splitlines() if "open files" in l), "(not said)"))

    preface = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
    host, port = grpc.split(":")
    for i in range(FLOOD):
        s = socket.create_connection((host, int(port)), timeout=5)
        s.sendall(preface)
        socks.append(s)
    time.sleep(1)
    held = len(os.listdir("/proc/%d/fd" % proc.pid))
    check(held > 1024, "rangexd holds %d files, past the 1024 it was started with" % held)

    st = subprocess.run([rangexctl, "status", "--server", grpc], capture_output=True, text=True,
                        timeout=60)
    check(st.returncode == 0 and "SERVING" in st.stdout,
          "with %d idle connections open, `rangexctl status` answers (%s)"
          % (FLOOD, (st.stdout + st.stderr).strip().splitlines()[0:1]))
    with urllib.request.urlopen("http://%s/api/lanes" % http, timeout=30) as r:
        check(r.status == 200, "and the dashboard's API answers")
finally:
    for s in socks:
        s.close()
    if not terminate(proc):
        fail("rangexd did not stop within 60 s of SIGTERM")
shutil.rmtree(tmp, ignore_errors=True)
print("PASS")
