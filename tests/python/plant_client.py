#!/usr/bin/env python3
"""An integrator's client of rangexd, written as one would from outside the project: Python,
gRPC, and the server's reflection for the API (no code or .proto from this repository).

It starts rangexd, then does what stopped the server before: several ingest streams at once
with lines refused in-band on lanes other streams feed, a camera that reconnects and resends
while its old stream is open, statistics polled throughout, encoder jumps of 1e8 and 1.5e11,
an encoder reset, an empty request; it checks per-service health and the status codes of bad
control calls, the statistics' accounting, and a graceful stop. Every wait is bounded: a hang
fails the test.

Then, as a supervisor sees it: with its store locked by another process (a backup) rangexd
cannot record decisions, says NOT_SERVING, and exits non-zero after exit_after_s.

usage: plant_client.py RANGEXD RANGEXCTL PLANT_YAML
"""
import os
import re
import signal
import sqlite3
import struct
import subprocess
import sys
import tempfile
import threading
import time

import grpc
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

from checks import check, fail

DEADLINE = 20  # seconds for any single call or ack
FRAME = 640 * 200
PIXELS = 480


# --- the reflection protocol, by hand (grpc.reflection.v1alpha, proto wire format) ---------

def varint(n):
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


def fields(buf):
    """(field number, wire type, value) of a serialised message; value is bytes or int."""
    i = 0
    while i < len(buf):
        key, i = read_varint(buf, i)
        num, wt = key >> 3, key & 7
        if wt == 0:
            v, i = read_varint(buf, i)
        elif wt == 2:
            n, i = read_varint(buf, i)
            v, i = buf[i:i + n], i + n
        elif wt == 1:
            v, i = buf[i:i + 8], i + 8
        elif wt == 5:
            v, i = buf[i:i + 4], i + 4
        else:
            raise ValueError("wire type %d" % wt)
        yield num, wt, v


def read_varint(buf, i):
    n = shift = 0
    while True:
        b = buf[i]
        i += 1
        n |= (b & 0x7F) << shift
        shift += 7
        if not b & 0x80:
            return n, i


def reflect(channel):
    """Message classes of the server's services, built from what reflection returns."""
    call = channel.stream_stream(
        "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
        request_serializer=lambda b: b, response_deserializer=lambda b: b)

    def ask(field, text):
        data = text.encode()
        return next(iter(call(iter([bytes([field << 3 | 2]) + varint(len(data)) + data]),
                              timeout=DEADLINE)))

    services = []
    for num, _, listing in fields(ask(7, "")):  # list_services_response
        if num != 6:
            continue
        for n, _, service in fields(listing):
            if n == 1:
                services += [name.decode() for k, _, name in fields(service) if k == 1]
    pool = descriptor_pool.DescriptorPool()
    seen = set()
    pending = ["rangex.v1.IngestService"]
    while pending:
        sym = pending.pop()
        for num, _, v in fields(ask(4, sym)):  # file_containing_symbol
            if num != 4:
                continue
            for n, _, raw in fields(v):
                fd = descriptor_pb2.FileDescriptorProto.FromString(raw)
                if fd.name not in seen:
                    seen.add(fd.name)
                    pool.Add(fd)
    classes = {}
    for name in ["LineScan", "StreamLinesRequest", "StreamLinesResponse", "GetStatisticsRequest",
                 "GetStatisticsResponse", "ListLanesRequest", "ListLanesResponse",
                 "UploadCalibrationRequest", "UploadCalibrationResponse", "ResetLaneRequest",
                 "ResetLaneResponse"]:
        classes[name] = message_factory.MessageFactory(pool).GetPrototype(
            pool.FindMessageTypeByName("rangex.v1." + name))
    return services, classes


class Api:
    def __init__(self, channel, m):
        self.m = m
        self.channel = channel

        def unary(method, req, resp):
            return channel.unary_unary(method, request_serializer=lambda x: x.SerializeToString(),
                                       response_deserializer=m[resp].FromString)

        self.stats = unary("/rangex.v1.ControlService/GetStatistics", "GetStatisticsRequest",
                           "GetStatisticsResponse")
        self.lanes = unary("/rangex.v1.ControlService/ListLanes", "ListLanesRequest",
                           "ListLanesResponse")
        self.reset = unary("/rangex.v1.ControlService/ResetLane", "ResetLaneRequest",
                           "ResetLaneResponse")
        self.upload = unary("/rangex.v1.CalibrationService/UploadCalibration",
                            "UploadCalibrationRequest", "UploadCalibrationResponse")
        self.ingest = channel.stream_stream(
            "/rangex.v1.IngestService/StreamLines",
            request_serializer=lambda x: x.SerializeToString(),
            response_deserializer=m["StreamLinesResponse"].FromString)

    def line(self, seq, lane, encoder):
        req = self.m["StreamLinesRequest"](sequence=seq)
        req.line.lane = lane
        req.line.encoder = encoder
        req.line.cam0 = bytes(FRAME)
        req.line.cam1 = bytes(FRAME)
        req.line.xray = struct.pack("<%dH" % PIXELS, *([3600] * PIXELS))
        return req

    def health(self, service):
        call = self.channel.unary_unary("/grpc.health.v1.Health/Check",
                                        request_serializer=lambda b: b,
                                        response_deserializer=lambda b: b)
        data = service.encode()
        try:
            resp = call((b"\x0a" + varint(len(data)) + data) if data else b"", timeout=DEADLINE)
        except grpc.RpcError as e:
            return e.code().name
        return {1: "SERVING", 2: "NOT_SERVING"}.get(dict((n, v) for n, _, v in fields(resp))
                                                   .get(1, 0), "UNKNOWN")


class Stream:
    """One ingest stream: sends requests as acks come back (a window), keeps every ack."""

    def __init__(self, api, window=16):
        self.api = api
        self.acks = []
        self.sem = threading.Semaphore(window)
        self.queue = []
        self.cv = threading.Condition()
        self.done = False
        self.error = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _requests(self):
        while True:
            with self.cv:
                while not self.queue and not self.done:
                    self.cv.wait()
                if not self.queue:
                    return
                req = self.queue.pop(0)
            self.sem.acquire()
            yield req

    def _run(self):
        try:
            for ack in self.api.ingest(self._requests(), timeout=300):
                self.acks.append(ack)
                self.sem.release()
        except grpc.RpcError as e:
            self.error = e

    def send(self, req):
        with self.cv:
            self.queue.append(req)
            self.cv.notify()

    def close(self, bound=120):
        with self.cv:
            self.done = True
            self.cv.notify()
        self.thread.join(bound)
        if self.thread.is_alive():
            fail("an ingest stream did not finish within %d s" % bound)
        if self.error:
            fail("an ingest stream failed: %s" % self.error)
        return self.acks


def start_server(rangexd, config, data, log, listen="127.0.0.1:0"):
    proc = subprocess.Popen([rangexd, "--config", config, "--listen", listen, "--http",
                             "127.0.0.1:0", "--data",
                             data], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    start = time.time()
    for line in proc.stdout:
        log.append(line)
        m = re.search(r"listening on (127\.0\.0\.1:\d+)", line)
        if m:
            threading.Thread(target=lambda: [log.append(x) for x in proc.stdout],
                             daemon=True).start()
            return proc, m.group(1)
        if time.time() - start > 30:
            break
    proc.kill()
    fail("rangexd did not start")


def stop(proc):
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            rc = proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            fail("rangexd did not stop within 30 s of SIGINT")
        check(rc == 0, "rangexd stops gracefully on SIGINT (exit %d)" % rc)


def main():
    rangexd, rangexctl, config = sys.argv[1], sys.argv[2], sys.argv[3]
    signal.signal(signal.SIGALRM, lambda *_: fail("the scenario did not finish within 280 s"))
    signal.alarm(280)
    with tempfile.TemporaryDirectory() as tmp:
        log = []
        proc, addr = start_server(rangexd, config, os.path.join(tmp, "data"), log)
        try:
            scenario(addr)
        finally:
            stop(proc)
        supervised(rangexd, rangexctl, config, tmp)
    print("plant client: all checks passed")


def supervised(rangexd, rangexctl, config, tmp):
    """A store another process holds: NOT_SERVING, then exit 3 after exit_after_s."""
    strict = os.path.join(tmp, "strict.yaml")
    with open(config) as src:
        text = src.read()
    text, n1 = re.subn(r"(?m)^(\s+stall_s:)\s*[0-9.]+", r"\1 0.5", text)
    text, n2 = re.subn(r"(?m)^(\s+exit_after_s:)\s*[0-9.]+", r"\1 1.5", text)
    if n1 != 1 or n2 != 1:
        fail("the plant configuration has no server.stall_s / server.exit_after_s to shorten")
    with open(strict, "w") as dst:
        dst.write(text)
    data = os.path.join(tmp, "held")
    log = []
    proc, addr = start_server(rangexd, strict, data, log)
    db = sqlite3.connect(os.path.join(data, "rangex.sqlite"), isolation_level=None, timeout=10)
    db.execute("BEGIN EXCLUSIVE")  # a backup holding the database
    feeder = subprocess.Popen([rangexctl, "feed", "--config", strict, "--server", addr,
                               "--simulate", "--lanes", "1", "--fillets", "1", "--seed", "3",
                               "--settle-for", "150"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        rc = proc.wait(60)
    except subprocess.TimeoutExpired:
        proc.kill()
        feeder.kill()
        print("".join(log[-20:]))
        fail("rangexd kept running for 60 s without being able to store decisions")
    text = "".join(log)
    check(rc == 3 and "store failed" in text,
          "rangexd exits 3 when it cannot store decisions for exit_after_s (exit %d)" % rc)
    # Nothing it accepted was durable: the feeder still holds every line and waits for a
    # server that can keep them.
    check(feeder.poll() is None, "the feeder waits for a server that can store its lines")
    db.execute("ROLLBACK")
    db.close()
    log2 = []
    proc, _ = start_server(rangexd, strict, data, log2, listen=addr)
    try:
        out, err = feeder.communicate(timeout=180)
    except subprocess.TimeoutExpired:
        feeder.kill()
        proc.kill()
        fail("the feeder did not finish within 180 s of the restart")
    check(feeder.returncode == 0 and "every lane settled" in out,
          "after the restart the feeder delivers every line and every outcome is stored (exit %d:"
          " %s %s)" % (feeder.returncode, out.strip().replace("\n", "; "), err.strip()[-300:]))
    rows = sqlite3.connect(os.path.join(data, "rangex.sqlite")).execute(
        "SELECT lane, decision FROM fillets").fetchall()
    check(len(rows) == 1 and rows[0][1] in ("pass", "reject"),
          "the fillet fed while the store was held is decided and stored once (%s)" % rows)
    stop(proc)


def scenario(addr):
    opts = [("grpc.max_send_message_length", 64 << 20),
            ("grpc.max_receive_message_length", 64 << 20)]
    channel = grpc.insecure_channel(addr, options=opts)
    grpc.channel_ready_future(channel).result(timeout=DEADLINE)
    services, m = reflect(channel)
    check({"rangex.v1.IngestService", "rangex.v1.ControlService"} <= set(services),
          "reflection lists the services (%s)" % ", ".join(sorted(services)))
    api = Api(channel, m)

    for svc in ["", "rangex.v1.IngestService", "rangex.v1.ResultsService",
                "rangex.v1.CalibrationService", "rangex.v1.ControlService"]:
        check(api.health(svc) == "SERVING", "health of '%s' is SERVING" % svc)
    check(api.health("rangex.v1.NoSuchService") == "NOT_FOUND", "an unknown service is NOT_FOUND")

    # Statistics polled throughout: every call must answer within its deadline.
    polls = {"n": 0, "error": None}
    stop = threading.Event()

    def poll():
        while not stop.is_set():
            try:
                api.stats(m["GetStatisticsRequest"](), timeout=DEADLINE)
                polls["n"] += 1
            except grpc.RpcError as e:
                polls["error"] = e
                return
            time.sleep(0.05)

    poller = threading.Thread(target=poll, daemon=True)
    poller.start()

    # Several streams at once. A feeds lane 0; B is A's camera reconnecting: it resends from
    # a little behind A while A is still open. C feeds lanes 1 and 2 and throws in
    # duplicates and lines going backwards on lanes 0 and 1, which A and C feed.
    a, b, c = Stream(api), Stream(api), Stream(api)
    seq = 0
    for e in range(0, 200):
        a.send(api.line(seq, 0, e)); seq += 1
    while len(a.acks) < 150:
        time.sleep(0.01)
    for e in range(140, 300):
        b.send(api.line(seq, 0, e)); seq += 1
    for e in range(200, 300):
        a.send(api.line(seq, 0, e)); seq += 1
    for e in range(0, 150):
        c.send(api.line(seq, 1, e)); seq += 1
        c.send(api.line(seq, 2, e)); seq += 1
        if e % 10 == 9:
            c.send(api.line(seq, 1, e - 3)); seq += 1  # duplicate on a lane C feeds
            c.send(api.line(seq, 0, 5)); seq += 1      # duplicate on lane 0 (A and B feed it)
            c.send(api.line(seq, 1, -100 - e)); seq += 1  # behind, never accepted
    acks = {"a": a.close(), "b": b.close(), "c": c.close()}
    check(len(acks["a"]) == 300 and len(acks["b"]) == 160 and len(acks["c"]) == 300 + 45,
          "every line of the three streams was acknowledged")
    codes = {}
    for s in acks.values():
        for k in s:
            if not k.accepted:
                codes[k.error.code] = codes.get(k.error.code, 0) + 1
    accepted0 = sum(1 for s in ("a", "b") for k in acks[s] if k.accepted)
    check(accepted0 == 300, "lane 0's 300 counts were each accepted once across A and B (%d)"
          % accepted0)
    check(set(codes) <= {"DUPLICATE_LINE", "ENCODER_BACKWARDS"} and
          codes.get("ENCODER_BACKWARDS") == 15,
          "refusals name their reason in-band (%s)" % codes)

    # Encoder jumps on lane 3: 1e8, then 1.5e11 (a PLC re-based); the server stays prompt.
    d = Stream(api)
    base = 0
    for jump in (0, 100_000_000, 150_000_000_000):
        base += jump
        for e in range(base, base + 50):
            d.send(api.line(seq, 3, e)); seq += 1
    t0 = time.time()
    jumps = d.close(60)
    check(all(k.accepted for k in jumps) and len(jumps) == 150,
          "lines after jumps of 1e8 and 1.5e11 are accepted (%.1f s)" % (time.time() - t0))
    wait_processed(api, m, "after the jumps")

    # An encoder reset: lane 3 starts again at 0 (far behind: recognised as a reset); lane 2
    # is reset through the control plane and then takes a count far behind its latest.
    e = Stream(api)
    for n in range(0, 20):
        e.send(api.line(seq, 3, n)); seq += 1
    api.reset(m["ResetLaneRequest"](lane=2, who="python-integrator", reason="PLC swap"),
              timeout=DEADLINE)
    e.send(api.line(seq, 2, 7)); seq += 1
    resets = e.close(60)
    check(all(k.accepted for k in resets), "lines after an encoder reset are accepted")
    wait_processed(api, m, "after the resets")
    lanes = {l.id: l for l in api.lanes(m["ListLanesRequest"](), timeout=DEADLINE).lanes}
    check(lanes[3].last_encoder == 19 and lanes[2].last_encoder == 7 and lanes[0].last_encoder == 299,
          "ListLanes shows each lane's last accepted encoder (%d, %d, %d)"
          % (lanes[0].last_encoder, lanes[2].last_encoder, lanes[3].last_encoder))
    check(lanes[3].restarts >= 2, "lane 3 restarted at the jump and at the reset (%d)"
          % lanes[3].restarts)

    # An empty request: refused, counted, with the true credit.
    before = api.stats(m["GetStatisticsRequest"](), timeout=DEADLINE)
    f = Stream(api)
    f.send(m["StreamLinesRequest"](sequence=seq)); seq += 1
    empty = f.close(30)
    quota = before.queue_capacity // max(1, len(lanes))  # one stream open, the plant's lanes
    check(len(empty) == 1 and empty[0].error.code == "MISSING_LINE" and empty[0].credit == quota,
          "an empty request is refused MISSING_LINE with the stream's true credit (%d of %d)"
          % (empty[0].credit, quota))
    g = Stream(api)
    g.send(m["StreamLinesRequest"](sequence=seq, credit_query=True)); seq += 1
    query = g.close(30)
    check(len(query) == 1 and not query[0].error.code and query[0].credit == quota,
          "a credit query is answered with the credit and no error (%d)" % query[0].credit)
    check(api.stats(m["GetStatisticsRequest"](), timeout=DEADLINE).lines_received ==
          before.lines_received + 1, "a credit query is not counted as a line")

    # Bad control calls get gRPC's meaning and a message that names the problem.
    try:
        api.upload(m["UploadCalibrationRequest"](lane=9, id="x", yaml="laser_plane: {}\n"),
                   timeout=DEADLINE)
        fail("a calibration for an unknown lane was accepted")
    except grpc.RpcError as err:
        check(err.code() == grpc.StatusCode.NOT_FOUND and "lane 9" in err.details(),
              "a calibration for an unknown lane is NOT_FOUND (%s)" % err.details())
    try:
        api.upload(m["UploadCalibrationRequest"](lane=0, id="blank", yaml=""), timeout=DEADLINE)
        fail("an empty calibration was accepted")
    except grpc.RpcError as err:
        check(err.code() == grpc.StatusCode.INVALID_ARGUMENT and ": :" not in err.details()
              and "empty" in err.details(),
              "an empty calibration names the problem (%s)" % err.details())

    stop.set()
    poller.join(DEADLINE)
    check(polls["error"] is None and polls["n"] > 5,
          "statistics answered all %d polls during ingest" % polls["n"])
    s = wait_processed(api, m, "at the end")
    refused = sum(r.lines for r in s.refused)
    dropped = sum(r.lines for r in s.dropped)
    check(s.lines_received == s.lines_accepted + refused,
          "received %d = accepted %d + refused %d" % (s.lines_received, s.lines_accepted, refused))
    check(s.lines_accepted == s.lines_processed + dropped,
          "accepted %d = processed %d + dropped %d" % (s.lines_accepted, s.lines_processed,
                                                      dropped))
    check(s.serving and api.health("") == "SERVING", "the server still says SERVING")


def wait_processed(api, m, when):
    start = time.time()
    while time.time() - start < 30:
        s = api.stats(m["GetStatisticsRequest"](), timeout=DEADLINE)
        if s.queue_depth == 0 and s.lines_processed + sum(r.lines for r in s.dropped) == \
                s.lines_accepted:
            return s
        time.sleep(0.05)
    fail("the server did not process its accepted lines within 30 s " + when)


if __name__ == "__main__":
    main()
