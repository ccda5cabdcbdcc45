"""What the Python tests report with: a check that passes prints `ok`, one that fails prints
`FAIL` with what failed and ends the test with exit status 1; and what they start rangexd
with."""
import signal
import socket
import subprocess
import sys


def fail(msg):
    print("FAIL:", msg, flush=True)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)
    print("ok  ", msg, flush=True)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def terminate(proc, timeout=60):
    """SIGTERM, as a plant stops rangexd; killed if it has not ended within `timeout` seconds.
    Whether it ended by itself."""
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout=timeout)
        return True
    except subprocess.TimeoutExpired:
        proc.kill()
        return False
