#!/usr/bin/env python3
"""Messages of hundreds of megabytes do not take rangexd's memory, and a feeder beside them
loses nothing.

gRPC (C++, chttp2) holds a message whole before it checks it against the largest it takes,
whatever the message declares (up to 4 GiB), and a unary call's message before any handler
sees the caller. Four 300 MB StreamLines messages took rangexd from 100 MB to 1.2 GB, each
then refused as larger than the 64 MB bound. server.grpc_memory_mb bounds what gRPC holds:
past it gRPC cuts streams, and clients see RESOURCE_EXHAUSTED.

Here rangexd runs with a 16 MB bound. Three clients at once each send one message of 128 MB
(two StreamLines, one UploadCalibration), while `rangexctl feed` feeds two lanes. Every
large message must be refused, rangexd's memory must grow by less than one of them (without
the bound it grew by 332 MB), and the feed must settle every line: a feeder whose stream is
cut reconnects and resends. Afterwards the server still answers.

usage: grpc_memory_test.py RANGEXD RANGEXCTL PLANT.yaml
"""
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

import grpc

from checks import check, fail, free_port, terminate

rangexd, rangexctl, plant = sys.argv[1:4]
MB = 1 << 20
SIZE = 128 * MB
signal.alarm(280)  # the whole test, whatever hangs


def varint(v):
    out = bytearray()
    while True:
        b, v = v & 0x7F, v >> 7
        out.append(b | 0x80 if v else b)
        if not v:
            return bytes(out)


def field(num, payload):  # a length-delimited protobuf field
    return varint(num << 3 | 2) + varint(len(payload)) + payload


def vm_kb(pid, key):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    fail("no %s in /proc/%d/status" % (key, pid))


tmp = tempfile.mkdtemp(prefix="rangex-grpcmem-")
text = open(plant).read()
check("\nserver:\n" in text, "plant.yaml has a server section")
cfg = os.path.join(tmp, "plant.yaml")
with open(cfg, "w") as f:
    f.write(text.replace("\nserver:\n", "\nserver:\n  grpc_memory_mb: 16\n", 1)
            .replace("  grpc_memory_mb: 256", "  # grpc_memory_mb: 256"))
addr = "127.0.0.1:%d" % free_port()
out = open(os.path.join(tmp, "rangexd.log"), "w")
proc = subprocess.Popen([rangexd, "--config", cfg, "--listen", addr, "--http", "off",
                         "--backend", "cpu", "--data", os.path.join(tmp, "data")],
                        stdout=out, stderr=subprocess.STDOUT)


def status():
    return subprocess.run([rangexctl, "status", "--server", addr], capture_output=True,
                          text=True, timeout=60)


try:
    end = time.time() + 60
    while time.time() < end:
        if proc.poll() is not None:
            fail("rangexd exited with %d at start: %s" % (proc.returncode, open(out.name).read()))
        if "SERVING" in status().stdout:
            break
        time.sleep(0.3)
    else:
        fail("rangexd did not answer within 60 s")

    # StreamLinesRequest{sequence 1, line{lane 0, encoder 1, cam0 of SIZE bytes}}, and
    # UploadCalibrationRequest{lane 0, id "huge", yaml of SIZE bytes}: raw bytes, no stubs.
    payload = bytes(SIZE)
    line_msg = b"\x08\x01" + field(2, b"\x08\x00\x10\x01" + field(4, payload))
    calib_msg = b"\x08\x00" + field(2, b"huge") + field(3, payload)
    del payload
    results = {}

    def send(name, method, msg, streaming):
        ch = grpc.insecure_channel(addr, options=[("grpc.max_send_message_length", -1),
                                                  ("grpc.max_receive_message_length", -1)])
        try:
            if streaming:
                call = ch.stream_stream(method, request_serializer=None,
                                        response_deserializer=None)
                for _ in call(iter([msg]), timeout=120):
                    results[name] = "answered"
                    break
            else:
                ch.unary_unary(method, request_serializer=None,
                               response_deserializer=None)(msg, timeout=120)
                results[name] = "answered"
        except grpc.RpcError as e:
            results[name] = "%s: %s" % (e.code().name, e.details())
        finally:
            ch.close()

    before = vm_kb(proc.pid, "VmRSS")
    feed = subprocess.Popen([rangexctl, "feed", "--server", addr, "--simulate", "--lanes", "2",
                             "--fillets", "6", "--seed", "3"], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    senders = [threading.Thread(target=send, args=(
        "lines %d" % i, "/rangex.v1.IngestService/StreamLines", line_msg, True))
        for i in range(2)]
    senders.append(threading.Thread(target=send, args=(
        "calibration", "/rangex.v1.CalibrationService/UploadCalibration", calib_msg, False)))
    for t in senders:
        t.start()
    for t in senders:
        t.join()
    peak = vm_kb(proc.pid, "VmHWM")
    fed, _ = feed.communicate(timeout=200)
    print("large messages:", results)
    print("rangexd resident %d MB before, peak %d MB" % (before // 1024, peak // 1024))
    print("feed:", " | ".join(fed.strip().splitlines()[-3:]))

    check(proc.poll() is None, "rangexd is running after the large messages")
    for name in ("lines 0", "lines 1", "calibration"):
        check(results.get(name, "").startswith("RESOURCE_EXHAUSTED"),
              "the %d MB %s message is refused with RESOURCE_EXHAUSTED (%s)"
              % (SIZE // MB, name, results.get(name)))
    grown = (peak - before) // 1024
    check(grown < SIZE // MB,
          "rangexd grew by %d MB, less than one of the three %d MB messages (held whole, "
          "they took it up by 332 MB)" % (grown, SIZE // MB))
    check(feed.returncode == 0 and "every lane settled" in fed,
          "the feed beside them settled every line (exit %d)" % feed.returncode)
    st = status()
    check("SERVING" in st.stdout and "fillets: 12 " in st.stdout,
          "rangexd serves and decided the feed's 12 fillets (%s)"
          % " | ".join(st.stdout.splitlines()[1:3]))
finally:
    if not terminate(proc):
        fail("rangexd did not stop within 60 s of SIGTERM")
shutil.rmtree(tmp, ignore_errors=True)
print("PASS")
