#!/usr/bin/env python3
"""An integrator's dry run of plant.yaml's plc section against a PLC program's smaller map.

`rangexctl plc-sim --registers 12` maps holding registers 0..11 only, as a PLC program may:
lane 0's state (10, 11) is mapped, lane 1's (12, 13) is not. rangexd, given plant.yaml with
that PLC, keeps the connection and names the refusal: `rangexctl status` says the PLC is
connected and refusing, and its warning names the registers, the part of the map and where
to look. Every process is rangex's own binary, as a plant runs them.

usage: plc_map_test.py RANGEXD RANGEXCTL PLANT.yaml
"""
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

from checks import check, fail, free_port, terminate

rangexd, rangexctl, plant = sys.argv[1:4]
signal.alarm(180)  # the whole test, whatever hangs
tmp = tempfile.mkdtemp(prefix="rangex-plcmap-")
port = free_port()
config = os.path.join(tmp, "plant.yaml")
with open(plant) as src, open(config, "w") as out:
    out.write(src.read() + "\nplc:\n  address: 127.0.0.1:%d\n" % port)

plc = subprocess.Popen([rangexctl, "plc-sim", "--config", config, "--registers", "12"],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
grpc = "127.0.0.1:%d" % free_port()
server = None
try:
    said = plc.stdout.readline()
    check("holding registers 0..11" in said, "plc-sim maps registers 0..11: " + said.strip())
    server = subprocess.Popen([rangexd, "--config", config, "--listen", grpc, "--http", "off",
                               "--backend", "cpu", "--data", os.path.join(tmp, "data")],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    status = ""
    end = time.time() + 60
    while time.time() < end and "REFUSING" not in status:
        if server.poll() is not None:
            fail("rangexd exited with %d" % server.returncode)
        st = subprocess.run([rangexctl, "status", "--server", grpc], capture_output=True,
                            text=True, timeout=30)
        status = st.stdout
        time.sleep(0.2)
    plc_line = next((l for l in status.splitlines() if l.startswith("PLC ")), "")
    check("connected, REFUSING registers" in plc_line, "status: " + plc_line)
    warning = next((l for l in status.splitlines() if "refuses registers" in l), "")
    for said in ("refuses registers 12..13", "a lane's state", "plant.yaml's plc section"):
        check(said in warning, "the warning says '%s': %s" % (said, warning))
finally:
    if server and not terminate(server):
        fail("rangexd did not stop within 60 s of SIGTERM")
    terminate(plc)
shutil.rmtree(tmp, ignore_errors=True)
print("PASS")
