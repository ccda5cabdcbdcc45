#!/usr/bin/env python3
"""rangexd over TLS as a plant's IT would set it up, with clients that are not ours: Python's
grpcio and urllib. A test CA from scripts/make-test-ca.sh, a token from `rangexctl token`,
and a plant.yaml whose security section names them.

Checks: a viewer certificate reads and is refused a write (PERMISSION_DENIED); an operator
token writes, and the audit (read from the store's SQLite file) names the token, not the
name the client sent; a client of another CA and a plaintext client get nothing; the
dashboard answers 401 without credentials and 200 with the token as Basic's password or
with the viewer certificate; rangexctl reaches the server with RANGEX_CA and
RANGEX_TOKEN_FILE; and rangexd refuses to start plaintext on 0.0.0.0.

usage: tls_client.py RANGEXD RANGEXCTL SOURCE_DIR
"""
import base64
import os
import re
import shutil
import signal
import sqlite3
import ssl
import struct
import subprocess
import sys
import tempfile
import urllib.error
import urllib.request

import grpc

from checks import check, fail

rangexd, rangexctl, source = sys.argv[1:4]
signal.alarm(300)  # the whole test, whatever hangs
tmp = tempfile.mkdtemp(prefix="rangex-tls-")
ca = os.path.join(tmp, "ca")
subprocess.run([os.path.join(source, "scripts/make-test-ca.sh"), ca], check=True,
               stdout=subprocess.DEVNULL, timeout=60)
pem = lambda name: os.path.join(ca, name)
token_file = os.path.join(tmp, "operator.token")
out = subprocess.run([rangexctl, "token", "--name", "py-operator", "--role", "operator",
                      "--out", token_file], check=True, capture_output=True, text=True,
                     timeout=30).stdout
entry = re.search(r"(- \{name: py-operator, role: operator, sha256: [0-9a-f]{64}\})", out)
check(entry is not None, "rangexctl token prints the plant.yaml entry")
token = open(token_file).read().strip()
check(token not in open(os.path.join(source, "config/plant.yaml")).read() and token not in entry.group(1),
      "the token itself appears nowhere in the configuration")

plant = os.path.join(tmp, "plant.yaml")
shutil.copy(os.path.join(source, "config/plant.yaml"), plant)
with open(plant, "a") as f:
    f.write(f"""
security:
  tls: {{cert: {pem('server.crt')}, key: {pem('server.key')}, client_ca: {pem('ca.crt')}}}
  identities: {{viewer-1: viewer}}
  tokens:
    {entry.group(1)}
""")

data = os.path.join(tmp, "data")
server = subprocess.Popen([rangexd, "--config", plant, "--listen", "127.0.0.1:0", "--http",
                           "127.0.0.1:0", "--data", data],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
grpc_addr = http_addr = None
try:
    while grpc_addr is None or http_addr is None:
        line = server.stdout.readline()
        if not line:
            fail("rangexd exited before it served: " + server.stderr.read())
        m = re.search(r"listening on (\S+),", line)
        grpc_addr = m.group(1) if m else grpc_addr
        m = re.search(r"dashboard at https://(\S+)/", line)
        http_addr = m.group(1) if m else http_addr

    root = open(pem("ca.crt"), "rb").read()

    def call(channel, method, request=b""):
        """A unary call with a hand-encoded request; returns (status code, response bytes)."""
        f = channel.unary_unary(method, request_serializer=None, response_deserializer=None)
        try:
            return grpc.StatusCode.OK, f(request, timeout=10)
        except grpc.RpcError as e:
            return e.code(), e.details()

    info = "/rangex.v1.ControlService/GetServerInfo"
    thresholds = "/rangex.v1.ControlService/UpdateLaneThresholds"
    # lane 0 (default), z_threshold (field 2, double) 4.25, who (field 5) "mallory"
    raise_z = b"\x11" + struct.pack("<d", 4.25) + b"\x2a\x07mallory"

    viewer = grpc.secure_channel(grpc_addr, grpc.ssl_channel_credentials(
        root, open(pem("viewer-1.key"), "rb").read(), open(pem("viewer-1.crt"), "rb").read()))
    code, _ = call(viewer, info)
    check(code == grpc.StatusCode.OK, "a viewer certificate reads server info")
    code, msg = call(viewer, thresholds, raise_z)
    check(code == grpc.StatusCode.PERMISSION_DENIED and "needs the operator role" in msg,
          "a viewer certificate may not change thresholds (%s: %s)" % (code, msg))

    operator = grpc.secure_channel(grpc_addr, grpc.composite_channel_credentials(
        grpc.ssl_channel_credentials(root), grpc.access_token_call_credentials(token)))
    code, msg = call(operator, thresholds, raise_z)
    check(code == grpc.StatusCode.OK,
          "an operator token changes thresholds" + ("" if code == grpc.StatusCode.OK else " (%s)" % msg))
    who = sqlite3.connect(os.path.join(data, "rangex.sqlite")).execute(
        "SELECT who FROM audit WHERE what = 'lane.thresholds'").fetchall()
    check(who == [("token:py-operator",)],
          "the audit names the token's identity, not the name the client sent (%s)" % who)

    rogue = grpc.secure_channel(grpc_addr, grpc.ssl_channel_credentials(
        root, open(pem("rogue-admin.key"), "rb").read(), open(pem("rogue-admin.crt"), "rb").read()))
    code, _ = call(rogue, info)
    check(code == grpc.StatusCode.UNAVAILABLE, "a certificate of another CA is refused (%s)" % code)
    code, _ = call(grpc.insecure_channel(grpc_addr), info)
    check(code == grpc.StatusCode.UNAVAILABLE, "a plaintext client is refused (%s)" % code)
    code, msg = call(grpc.secure_channel(grpc_addr, grpc.ssl_channel_credentials(root)), info)
    check(code == grpc.StatusCode.UNAUTHENTICATED, "no credentials: UNAUTHENTICATED (%s)" % msg)

    ctx = ssl.create_default_context(cafile=pem("ca.crt"))

    def get(path, headers=None, context=ctx):
        req = urllib.request.Request("https://%s%s" % (http_addr, path), headers=headers or {})
        try:
            with urllib.request.urlopen(req, context=context, timeout=10) as r:
                return r.status, r.read()
        except urllib.error.HTTPError as e:
            return e.code, e.read()

    status, body = get("/api/info")
    check(status == 401, "the dashboard without credentials: 401 (%s)" % body[:80])
    basic = base64.b64encode(("operator:" + token).encode()).decode()
    status, _ = get("/api/info", {"Authorization": "Basic " + basic})
    check(status == 200, "the dashboard with the token as Basic's password: 200")
    cert_ctx = ssl.create_default_context(cafile=pem("ca.crt"))
    cert_ctx.load_cert_chain(pem("viewer-1.crt"), pem("viewer-1.key"))
    status, _ = get("/metrics", context=cert_ctx)
    check(status == 200, "/metrics with the viewer certificate: 200")

    env = dict(os.environ, RANGEX_CA=pem("ca.crt"), RANGEX_TOKEN_FILE=token_file)
    r = subprocess.run([rangexctl, "status", "--server", grpc_addr], env=env, capture_output=True,
                       text=True, timeout=30)
    check(r.returncode == 0 and "SERVING" in r.stdout,
          "rangexctl with RANGEX_CA and RANGEX_TOKEN_FILE (%s)" % r.stderr.strip())
    r = subprocess.run([rangexctl, "status", "--server", grpc_addr], capture_output=True, text=True,
                       timeout=30)
    check(r.returncode != 0 and "give its CA" in r.stderr,
          "rangexctl without the CA says what to give (%s)" % r.stderr.strip())
finally:
    server.terminate()
    server.wait(timeout=60)

r = subprocess.run([rangexd, "--listen", "0.0.0.0:0", "--http", "off", "--data",
                    os.path.join(tmp, "open")], capture_output=True, text=True, timeout=60)
check(r.returncode != 0 and "without TLS" in r.stderr and "security.insecure" in r.stderr,
      "rangexd refuses plaintext on 0.0.0.0 (%s)" % r.stderr.strip().splitlines()[-1])
shutil.rmtree(tmp, ignore_errors=True)
print("tls_client: all checks passed")
