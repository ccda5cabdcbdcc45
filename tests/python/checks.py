"""What the Python tests report with: a check that passes prints `ok`, one that fails prints
`FAIL` with what failed and ends the test with exit status 1."""
import sys


def fail(msg):
    print("FAIL:", msg, flush=True)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)
    print("ok  ", msg, flush=True)
