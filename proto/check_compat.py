#!/usr/bin/env python3
"""Checks that proto/rangex/v1 keeps its word to every client written against its last release.

The released state is a descriptor set (proto/released/rangex.v1.binpb, what `buf build` calls an
image). The current protos are compiled with protoc and compared with it, by the rules of buf's
WIRE_JSON and FILE categories that a v1 promises:
  - every released file, package, message, enum, service and method is still there;
  - a field keeps its number, name, JSON name, type, cardinality and oneof;
  - a field or enum value is removed only with its number and name reserved;
  - a method keeps its request and response types and its streaming.
Adding is always allowed. A break goes to v2.

usage: check_compat.py [--protoc PROTOC] [--root DIR] [--released FILE] [--write-release]
  --write-release  makes the current protos the released state (at a release, never to pass CI)
Exit 0 compatible, 1 a break (each one named on stderr), 2 cannot check.
"""
import argparse
import os
import subprocess
import sys
import tempfile

from google.protobuf import descriptor_pb2

HERE = os.path.dirname(os.path.abspath(__file__))
LABELS = {1: "optional", 2: "required", 3: "repeated"}


def compile_protos(protoc, root):
    files = []
    for base, _, names in os.walk(os.path.join(root, "rangex")):
        files += [os.path.relpath(os.path.join(base, n), root) for n in names if n.endswith(".proto")]
    if not files:
        sys.exit(f"check_compat: no .proto files under {root}/rangex")
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "current.binpb")
        run = subprocess.run([protoc, "-I", root, "--descriptor_set_out=" + out] + sorted(files),
                             capture_output=True, text=True)
        if run.returncode != 0:
            print(f"check_compat: protoc failed:\n{run.stderr}", file=sys.stderr)
            sys.exit(2)
        with open(out, "rb") as f:
            data = f.read()
    fds = descriptor_pb2.FileDescriptorSet()
    fds.ParseFromString(data)
    return fds


def reserved(container, number, name):
    by_number = any(r.start <= number < r.end for r in container.reserved_range)
    return by_number, name in container.reserved_name


def field_type(f):
    t = descriptor_pb2.FieldDescriptorProto.Type.Name(f.type)[5:].lower()
    return f"{t} {f.type_name}".strip()


def cardinality(f):
    if f.label == 3:
        return "repeated"
    return "optional" if f.proto3_optional else "singular"


def oneof_of(msg, f):
    if not f.HasField("oneof_index") or f.proto3_optional:
        return None
    return msg.oneof_decl[f.oneof_index].name


def compare_enum(where, old, new, breaks):
    values = {v.number: v for v in new.value}
    for v in old.value:
        now = values.get(v.number)
        if now is None:
            num, name = reserved(new, v.number, v.name)
            if not (num and name):
                breaks.append(f"{where}: value {v.name} = {v.number} removed without reserving "
                              f"its number and name")
        elif now.name != v.name:
            breaks.append(f"{where}: value {v.number} was {v.name}, now {now.name}")


def compare_message(where, old, new, breaks):
    fields = {f.number: f for f in new.field}
    for f in old.field:
        at = f"{where} field {f.number} ({f.name})"
        now = fields.get(f.number)
        if now is None:
            num, name = reserved(new, f.number, f.name)
            if not (num and name):
                breaks.append(f"{at}: removed without reserving its number and name")
            continue
        if now.name != f.name:
            breaks.append(f"{at}: renamed to {now.name}")
        elif now.json_name != f.json_name:
            breaks.append(f"{at}: JSON name {f.json_name} became {now.json_name}")
        if field_type(now) != field_type(f):
            breaks.append(f"{at}: type {field_type(f)} became {field_type(now)}")
        if cardinality(now) != cardinality(f):
            breaks.append(f"{at}: {cardinality(f)} became {cardinality(now)}")
        if oneof_of(new, now) != oneof_of(old, f):
            breaks.append(f"{at}: oneof {oneof_of(old, f)} became {oneof_of(new, now)}")
    compare_nested(where, old, new, breaks)


def messages_of(d):
    return d.message_type if isinstance(d, descriptor_pb2.FileDescriptorProto) else d.nested_type


def compare_nested(where, old, new, breaks):
    messages = {m.name: m for m in messages_of(new)}
    for m in messages_of(old):
        if m.name not in messages:
            breaks.append(f"{where}.{m.name}: message removed")
        else:
            compare_message(f"{where}.{m.name}", m, messages[m.name], breaks)
    enums = {e.name: e for e in new.enum_type}
    for e in old.enum_type:
        if e.name not in enums:
            breaks.append(f"{where}.{e.name}: enum removed")
        else:
            compare_enum(f"{where}.{e.name}", e, enums[e.name], breaks)


def compare_file(old, new, breaks):
    where = f"{old.name}: {old.package}"
    if new.package != old.package:
        breaks.append(f"{old.name}: package {old.package} became {new.package}")
    compare_nested(where, old, new, breaks)
    services = {s.name: s for s in new.service}
    for s in old.service:
        now = services.get(s.name)
        if now is None:
            breaks.append(f"{where}.{s.name}: service removed")
            continue
        methods = {m.name: m for m in now.method}
        for m in s.method:
            at = f"{where}.{s.name}/{m.name}"
            n = methods.get(m.name)
            if n is None:
                breaks.append(f"{at}: method removed")
                continue
            if (n.input_type, n.output_type) != (m.input_type, m.output_type):
                breaks.append(f"{at}: {m.input_type} -> {m.output_type} became "
                              f"{n.input_type} -> {n.output_type}")
            if (n.client_streaming, n.server_streaming) != (m.client_streaming,
                                                            m.server_streaming):
                breaks.append(f"{at}: streaming changed")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--protoc", default="protoc")
    ap.add_argument("--root", default=HERE)
    ap.add_argument("--released", default=os.path.join(HERE, "released", "rangex.v1.binpb"))
    ap.add_argument("--write-release", action="store_true")
    a = ap.parse_args()
    current = compile_protos(a.protoc, a.root)
    if a.write_release:
        with open(a.released, "wb") as f:
            f.write(current.SerializeToString(deterministic=True))
        print(f"check_compat: {a.released} is now the released state")
        return 0
    try:
        with open(a.released, "rb") as f:
            released = descriptor_pb2.FileDescriptorSet.FromString(f.read())
    except OSError as e:
        print(f"check_compat: cannot read the released state {a.released}: {e}", file=sys.stderr)
        return 2
    files = {f.name: f for f in current.file}
    breaks = []
    for old in released.file:
        if old.name not in files:
            breaks.append(f"{old.name}: file removed (or moved)")
        else:
            compare_file(old, files[old.name], breaks)
    for b in breaks:
        print(f"BREAKING: {b}", file=sys.stderr)
    if breaks:
        print(f"check_compat: {len(breaks)} breaking change(s) against {a.released}; "
              f"a break goes to a new version (rangex.v2)", file=sys.stderr)
        return 1
    print(f"check_compat: compatible with {os.path.basename(a.released)} "
          f"({sum(len(f.message_type) for f in released.file)} messages, "
          f"{sum(len(f.service) for f in released.file)} services)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
