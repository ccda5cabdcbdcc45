#!/usr/bin/env python3
"""Writes the fuzz targets' seed corpus (tests/fuzz/corpus/<target>/): small valid inputs of
each kind, in each target's input format, for libFuzzer to mutate from. Run from anywhere;
the corpus is committed, this script is how it was made.

usage: make_seeds.py [CORPUS_DIR]
"""
import io
import os
import struct
import sys
import zipfile

here = os.path.dirname(os.path.abspath(__file__))
out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "corpus")


def put(target, name, data):
    d = os.path.join(out, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def fdp_strings(*parts):
    """FuzzedDataProvider.ConsumeRandomLengthString's encoding: a backslash is doubled, and a
    backslash followed by another byte ends the string."""
    return b"".join(p.replace(b"\\", b"\\\\") + b"\\\n" for p in parts)


def varint(n):
    n &= (1 << 64) - 1
    b = bytearray()
    while True:
        b.append((n & 0x7F) | (0x80 if n > 0x7F else 0))
        n >>= 7
        if not n:
            return bytes(b)


def field(num, wire, payload):
    key = varint(num << 3 | wire)
    return key + (varint(payload) if wire == 0 else varint(len(payload)) + payload)


def request(seq, lane, encoder, w, h, px, cal=b""):
    line = (field(1, 0, lane) + field(2, 0, encoder) + field(4, 2, bytes(w * h)) +
            field(5, 2, bytes(range(w * h))) + field(6, 2, struct.pack("<%dH" % px, *range(px))))
    if cal:
        line += field(7, 2, cal)
    return field(1, 0, seq) + field(2, 2, line)


# plant.yaml and calibration sets
root = os.path.join(here, "..", "..")
put("plant_config", "shipped.yaml", open(os.path.join(root, "config", "plant.yaml")).read())
put("plant_config", "minimal.yaml", "lanes: [{id: 0}]\n")
# A lane with thresholds learned from its product (rangexctl learn writes such a section).
put("plant_config", "learned.yaml", """lanes:
  - id: 0
    inspection:
      false_reject_target: 0.003
      spread: fillet
      learned:
        version: "learn-1"
        learned_on: "clean lane 0"
        target_frr: 0.003
        confidence: 0.9
        fillets: 40
        spread: fillet
        band_edges_mm: [0, 5, 10, 1000]
        sensitivity: ["1.5 mm calcified sphere at 95 % up to 25 mm of meat"]
        round:
          thresholds: [5.67, 5.72, 5.96]
          band_fraction: [1, 1, 0.9]
          band_pixels: [8000, 12000, 9000]
          band_thickness_mm: [2.5, 7.4, 12.1]
          model: {m0: 3.1, m_logn: 0.1, m_t: 0.02, s0: -0.9, s_t: 0.01, xi: 0.05, log_n_ref: 9.1, t_ref: 12}
        needle:
          thresholds: [6.1, 6.09, 6.33]
          band_fraction: [1, 1, 0.9]
          band_pixels: [8000, 12000, 9000]
          band_thickness_mm: [2.5, 7.4, 12.1]
          model: {m0: 3.3, m_logn: 0.1, m_t: 0.02, s0: -0.8, s_t: 0.01, xi: 0, log_n_ref: 9.1, t_ref: 12}
        air:
          thresholds: [80.6, 76.5, 96.1]
          model: {m0: 2.4, m_logn: 0.4, m_t: 0.01, s0: -0.7, s_t: 0.04, xi: 0.6, log_n_ref: 9.1, t_ref: 12}
""")
put("plant_config", "sections.yaml", """plant: {name: p, listen: 127.0.0.1:1, http: off}
server: {queue_lines: 64, batch_lines: 8}
retention: {days: 30, images_days: 7, every_h: 0.5}
security:
  tls: {cert: s.crt, key: s.key, client_ca: ca.crt}
  identities: {line-1: operator}
  tokens: [{name: t, role: viewer, sha256: %s}]
lanes:
  - {id: 0, frame: {width: 64, height: 20}, stripe: {method: gaussian3}}
  - {id: 2, encoder_step_mm: 0.5, xray: {pixels: 100, delay_lines: 10}}
""" % ("ab" * 32))
put("plant_config", "calibration.yaml",
    "laser_plane: {normal: [0, 1, 0], offset_mm: 0.05}\nencoder_step_mm: 0.41\n")

# recordings: a valid one-lane, two-line recording, and one whose arrays are short
yaml = (b"format: rangex-recording/1\nlanes: [0]\nframe: {width: 4, height: 2}\n"
        b"xray_pixels: 3\nlines: 2\nencoder_step_mm: 0.4\ncalibration_id: c\n")
cam = bytes(range(16))
put("recording", "valid", fdp_strings(yaml, cam, cam[::-1], struct.pack("<6H", *range(6)),
                                      struct.pack("<2q", 7, 8)))
put("recording", "short", fdp_strings(yaml, cam[:9], cam, b"\x01\x02", struct.pack("<q", 7)))

# LineScan requests: right sizes (lane 0 is 8x4 with 6 pixels in the target), a resend, a
# count far back (a reset), a wrong size, an unknown lane, encoders at the range's edges
reqs = [request(0, 0, 10, 8, 4, 6), request(1, 0, 11, 8, 4, 6), request(2, 0, 10, 8, 4, 6),
        request(3, 3, 5, 16, 2, 4, b"cal-1"), request(4, 0, 10 - 5000, 8, 4, 6),
        request(5, 0, 12, 8, 3, 6), request(6, 9, 1, 8, 4, 6),
        request(7, 0, (1 << 62), 8, 4, 6), request(8, 0, -(1 << 62) - 1, 8, 4, 6),
        field(1, 0, 9) + field(3, 0, 1)]
put("line_admission", "sequence", fdp_strings(*reqs))
put("line_admission", "one", fdp_strings(reqs[0]))

# queries: path "uid/kind", then ?parameters
for i, q in enumerate(["12/overlay?lane=1&decision=reject&limit=5",
                       "?from_ns=0&to_ns=5000&newest=1&after=3",
                       "7/residual?lanes=1,2&decisions=reject,pass&minutes=30&limit=10",
                       "99999999999999999999/xray?lane=-1&limit=0",
                       "3?decision=&lane=2&from_ns=2000",
                       # a dashboard action's body, and requests at the HTTP gate
                       '{"piece": "2 mm sphere", "x_mm": 40.5, "fillets": 3}',
                       "POST /api/lanes/1/verification HTTP/1.1\r\nContent-Length: 12\r\n\r\n"
                       '{"x_mm": 1}',
                       "POST /x HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n5\r\n"]):
    put("query_params", "q%d" % i, q)
# zipped GenICam descriptions as devices ship them: deflated, stored, two files, bytes before
xml = (b'<?xml version="1.0"?><RegisterDescription ModelName="Seed" VendorName="rangex">'
       b'<Category Name="Root"/></RegisterDescription>')
for name, method, files, prefix in [("deflated", zipfile.ZIP_DEFLATED, 1, b""),
                                    ("stored", zipfile.ZIP_STORED, 1, b""),
                                    ("two_files", zipfile.ZIP_DEFLATED, 2, b""),
                                    ("prefixed", zipfile.ZIP_DEFLATED, 1, b"MZ" * 20)]:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", method) as z:
        for f in range(files):
            info = zipfile.ZipInfo("desc%d.xml" % f, date_time=(2026, 12, 8, 0, 0, 0))
            info.compress_type = method
            z.writestr(info, xml * (f + 1))
    put("genicam_zip", name, prefix + buf.getvalue())
print("seeds written to", out)
