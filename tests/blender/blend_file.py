"""A saved .blend, block by block, to tell whether two saves hold the same data.

Blender saves the same session to the same bytes, but two saves of equal data can differ where
no data is: runtime fields Blender writes as they are (ID.recalc_after_undo_push, the
depsgraph's update tags since the last undo step; members of a *Runtime type, such as a cache
the sequencer made; the sharing handles of shared arrays, memory addresses), the pointer values
(stand-ins numbered in the order of writing, so a block written and removed earlier renumbers
all later ones; shared arrays keep their memory address) and the order of some blocks.
canonical() clears the runtime fields, replaces each pointer by a digest of the block it points
to (pointers are the members the file's SDNA declares as such; Blender 5 numbers each ID's data
blocks on its own, so a pointer is looked up among its own ID's blocks first), and sorts the
blocks; everything else is compared byte for byte.
"""
from __future__ import annotations

import hashlib
import re
import struct
from collections import Counter

HEADER = 17  # "BLENDER17-01v0500": 64-bit pointers, little-endian, large block headers
BHEAD = struct.Struct("<4siQqq")  # code, SDNA index, old address, length, count


def blocks(data: bytes) -> list:
    """(code, sdna index, old address, count, body) per block, in file order."""
    if not data.startswith(b"BLENDER17"):
        raise ValueError(f"not an uncompressed Blender 5 .blend: {data[:17]!r}")
    out, pos = [], HEADER
    while pos + BHEAD.size <= len(data):
        code, sdna, old, length, count = BHEAD.unpack_from(data, pos)
        body = data[pos + BHEAD.size:pos + BHEAD.size + length]
        out.append((code.rstrip(b"\0").decode("latin1"), sdna, old, count, body))
        pos += BHEAD.size + length
        if code == b"ENDB":
            break
    return out


def _sdna(body: bytes) -> tuple:
    """(struct type names by SDNA index, {struct name: [(type, field name)]}, {type: size})."""
    pos = 8  # "SDNA", "NAME"

    def strings(pos):
        count = struct.unpack_from("<i", body, pos)[0]
        pos += 4
        out = []
        for _ in range(count):
            end = body.index(b"\0", pos)
            out.append(body[pos:end].decode())
            pos = end + 1
        return out, (pos + 3) & ~3

    names, pos = strings(pos)
    types, pos = strings(pos + 4)  # "TYPE"
    sizes = struct.unpack_from(f"<{len(types)}h", body, pos + 4)  # "TLEN"
    pos = (pos + 4 + 2 * len(types) + 3) & ~3
    count = struct.unpack_from("<i", body, pos + 4)[0]  # "STRC"
    pos += 8
    order, fields = [], {}
    for _ in range(count):
        t, n = struct.unpack_from("<hh", body, pos)
        pos += 4
        members = []
        for _ in range(n):
            ft, fn = struct.unpack_from("<hh", body, pos)
            pos += 4
            members.append((types[ft], names[fn]))
        order.append(types[t])
        fields[types[t]] = members
    return order, fields, dict(zip(types, sizes))


def _members(fields: dict, sizes: dict, struct_name: str, cache: dict) -> tuple:
    """(runtime ranges, pointer offsets) of a struct, nested structs included: the runtime
    members (offset, size), and the offset of every pointer member as the SDNA declares it."""
    if struct_name in cache:
        return cache[struct_name]
    runtime, pointers, offset = [], [], 0
    for kind, name in fields.get(struct_name, []):
        pointer = name.startswith(("*", "(*"))
        size = 8 if pointer else sizes[kind]
        count = 1
        for extent in re.findall(r"\[(\d+)\]", name):
            count *= int(extent)
        # Runtime members, and the sharing handles of shared arrays (memory addresses).
        if name.lstrip("*_") == "runtime" or kind.endswith(("Runtime", "SharingInfoHandle")) or \
                name == "recalc_after_undo_push":
            runtime.append((offset, size * count))
        elif pointer:
            pointers += [offset + 8 * k for k in range(count)]
        elif kind in fields:
            inner_runtime, inner_pointers = _members(fields, sizes, kind, cache)
            for k in range(count):
                runtime += [(offset + k * size + at, n) for at, n in inner_runtime]
                pointers += [offset + k * size + at for at in inner_pointers]
        offset += size * count
    cache[struct_name] = (runtime, pointers)
    return cache[struct_name]


def canonical(data: bytes) -> list:
    """The blocks, sorted, with runtime members cleared and each pointer replaced by a digest of
    the block it points to (its type and bytes, its own pointers zeroed): equal for two saves of
    the same data, whatever order or addresses Blender wrote them in. A pointer to a block the
    file does not hold is 'loose', whatever its value.

    Blender 5 numbers the data blocks of each ID on its own (the same stand-in can name a block
    of another mesh): a pointer names a data block of its own ID, or an ID."""
    items = blocks(data)
    order, fields, sizes = _sdna(next(body for code, *_, body in items if code == "DNA1"))
    cache: dict = {}
    base = max((old >> 32 for _, _, old, _, _ in items if old), key=[old >> 32 for *_, old, _, _ in items].count)
    owners, owner = [], -1  # the index of the ID block each block belongs to
    for index, (code, *_rest) in enumerate(items):
        if code != "DATA":
            owner = index
        owners.append(owner)
    local = {(owners[i], old) for i, (code, _, old, _, _) in enumerate(items) if old and code == "DATA"}
    ids = {old for code, _, old, _, _ in items if old and code != "DATA"}
    cleared = []
    for (code, sdna, old, count, body), scope in zip(items, owners):
        body = bytearray(body)
        kind = order[sdna] if sdna < len(order) else str(sdna)
        stride = sizes.get(kind, 0) if code not in {"DNA1", "TEST", "REND", "ENDB"} else 0
        pointers = []
        if stride and kind in fields and stride * count == len(body):
            # A typed block: the SDNA says which members are runtime and which are pointers.
            runtime, offsets = _members(fields, sizes, kind, cache)
            for k in range(count):
                for at, n in runtime:
                    body[k * stride + at:k * stride + at + n] = bytes(n)
                for at in offsets:
                    at += k * stride
                    pointers.append((at, int.from_bytes(body[at:at + 8], "little")))
                    body[at:at + 8] = bytes(8)
        elif code not in {"DNA1", "TEST"}:
            # Raw data (arrays of pointers among them): a word is a pointer if it names a block
            # or looks like the file's stand-ins.
            for at in range(0, len(body) - 7, 8):
                word = int.from_bytes(body[at:at + 8], "little")
                if (scope, word) in local or word in ids or word >> 32 == base:
                    pointers.append((at, word))
                    body[at:at + 8] = bytes(8)
        cleared.append((code, kind, old, count, stride, bytes(body), pointers, scope))
    digest = {}
    for code, kind, old, count, _, body, _, scope in cleared:
        if old:
            digest[(scope, old) if code == "DATA" else old] = hashlib.sha1(f"{code}{kind}{count}".encode() + body).digest()[:8]
    out = []
    for code, kind, old, count, _, body, pointers, scope in cleared:
        body = bytearray(body)
        for at, word in pointers:
            if word:
                body[at:at + 8] = digest.get((scope, word), digest.get(word, b"loose\0\0\0"))
        out.append((code, kind, count, bytes(body)))
    return sorted(out)


def differences(a: bytes, b: bytes, limit: int = 8) -> list:
    """Up to `limit` descriptions of what differs between two saves (canonically): blocks only
    in one of them, by type."""
    ca, cb = canonical(a), canonical(b)
    if ca == cb:
        return []
    only_a = Counter(ca) - Counter(cb)
    only_b = Counter(cb) - Counter(ca)
    found = [f"{k[0]} {k[1]} only before ({len(k[3])} bytes)" for k in only_a]
    found += [f"{k[0]} {k[1]} only after ({len(k[3])} bytes)" for k in only_b]
    return found[:limit]


def explain(a: bytes, b: bytes, limit: int = 4) -> list:
    """For blocks that differ (canonically) between two saves, pairs of the same type and size:
    the struct members at the differing bytes, with both values, to trace what changed."""
    ca, cb = canonical(a), canonical(b)
    only_a = list((Counter(ca) - Counter(cb)).elements())
    only_b = list((Counter(cb) - Counter(ca)).elements())
    order, fields, sizes = _sdna(next(body for code, *_, body in blocks(a) if code == "DNA1"))
    out = []
    for x in only_a[:limit]:
        for y in only_b:
            if x[:3] != y[:3] or len(x[3]) != len(y[3]):
                continue
            stride = sizes.get(x[1], 0) or len(x[3])
            members, offset = [], 0
            for kind, name in fields.get(x[1], []):
                size = 8 if name.startswith(("*", "(*")) else sizes[kind]
                for extent in re.findall(r"\[(\d+)\]", name):
                    size *= int(extent)
                members.append((offset, size, name))
                offset += size
            for at in range(len(x[3])):
                if x[3][at] != y[3][at]:
                    k, rel = divmod(at, stride)
                    name = next((n for o, s, n in members if o <= rel < o + s), "?")
                    out.append(f"{x[1]}[{k}].{name} @{rel}: {x[3][at]:#04x} -> {y[3][at]:#04x}")
            break
    return out[:64]
