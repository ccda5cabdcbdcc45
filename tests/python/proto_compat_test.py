#!/usr/bin/env python3
"""The API compatibility check fails on each kind of break and passes what a v1 may add.

Each case edits a copy of proto/rangex/v1 and runs proto/check_compat.py against the committed
released state. usage: proto_compat_test.py SOURCE_DIR [PROTOC]
"""
import os
import shutil
import subprocess
import sys
import tempfile

SRC = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else ".")
PROTOC = sys.argv[2] if len(sys.argv) > 2 else "protoc"
CHECK = os.path.join(SRC, "proto", "check_compat.py")
PROTO = os.path.join("rangex", "v1", "rangex.proto")

STATS_4 = "  repeated ReasonCount refused = 4;  // at admission, by code\n"
BREAKS = [
    # (what, old text, new text, words the failure must name)
    # Renumbered to a number no field will take soon (30 was free until it was added).
    ("a renumbered field", "  uint64 lines_processed = 3;", "  uint64 lines_processed = 1000;",
     "GetStatisticsResponse field 3 (lines_processed): removed"),
    ("a renamed field (field 4 was drops, then refused)", STATS_4,
     "  repeated ReasonCount drops = 4;\n", "field 4 (refused): renamed to drops"),
    ("a retyped field", "  int32 queue_depth = 6;", "  int64 queue_depth = 6;",
     "field 6 (queue_depth): type int32 became int64"),
    ("a field made repeated", "  string backend = 8;", "  repeated string backend = 8;",
     "field 8 (backend): singular became repeated"),
    ("a field deleted without reserving", STATS_4, "",
     "field 4 (refused): removed without reserving"),
    ("a removed method", "  rpc GetFillet(GetFilletRequest) returns (GetFilletResponse);\n", "",
     "ResultsService/GetFillet: method removed"),
    ("a method's streaming changed",
     "  rpc GetFillet(GetFilletRequest) returns (GetFilletResponse);",
     "  rpc GetFillet(GetFilletRequest) returns (stream GetFilletResponse);",
     "ResultsService/GetFillet: streaming changed"),
    ("a renamed enum value", "  DECISION_REJECT = 2;", "  DECISION_REJECTED = 2;",
     "Decision: value 2 was DECISION_REJECT, now DECISION_REJECTED"),
    ("a renamed package", "package rangex.v1;", "package rangex.v1beta;",
     "package rangex.v1 became rangex.v1beta"),
]
ALLOWED = [
    ("a new field", "  int32 subscribers = 12;",
     "  int32 subscribers = 12;\n  uint64 added_for_test = 999;"),
    ("a new enum value", "  DECISION_NOT_INSPECTED = 3;",
     "  DECISION_NOT_INSPECTED = 3;\n  DECISION_ADDED_FOR_TEST = 99;"),
    ("a deleted field with its number and name reserved", STATS_4,
     "  reserved 4;\n  reserved \"refused\";\n"),
    ("a new method", "  rpc GetFillet(GetFilletRequest) returns (GetFilletResponse);",
     "  rpc GetFillet(GetFilletRequest) returns (GetFilletResponse);\n"
     "  rpc GetFilletAgain(GetFilletRequest) returns (GetFilletResponse);"),
]


def check(root):
    return subprocess.run([sys.executable, CHECK, "--protoc", PROTOC, "--root", root],
                          capture_output=True, text=True, timeout=120)


def edited(tmp, old, new):
    root = os.path.join(tmp, "case")
    shutil.rmtree(root, ignore_errors=True)
    shutil.copytree(os.path.join(SRC, "proto", "rangex"), os.path.join(root, "rangex"))
    path = os.path.join(root, PROTO)
    with open(path) as f:
        text = f.read()
    if text.count(old) != 1:
        raise SystemExit(f"FAIL: the case's text is not in {PROTO} once: {old!r}")
    with open(path, "w") as f:
        f.write(text.replace(old, new))
    return root


def main():
    failures = 0
    r = check(os.path.join(SRC, "proto"))
    if r.returncode != 0:
        print(f"FAIL: the committed proto is not compatible with its release:\n{r.stderr}")
        failures += 1
    with tempfile.TemporaryDirectory() as tmp:
        for what, old, new, words in BREAKS:
            r = check(edited(tmp, old, new))
            if r.returncode != 1 or words not in r.stderr:
                print(f"FAIL: {what}: exit {r.returncode}, expected 1 naming {words!r}:\n"
                      f"{r.stdout}{r.stderr}")
                failures += 1
            else:
                print(f"ok: {what} is refused")
        for what, old, new in ALLOWED:
            r = check(edited(tmp, old, new))
            if r.returncode != 0:
                print(f"FAIL: {what} should be allowed: exit {r.returncode}\n{r.stderr}")
                failures += 1
            else:
                print(f"ok: {what} is allowed")
    print(f"{failures} failure(s)" if failures else "all cases as expected")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
