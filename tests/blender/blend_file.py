"""A saved .blend, block by block, to tell whether two saves hold the same data.

Blender saves the same session to the same bytes, but two saves of equal data can differ where
no data is: runtime fields Blender writes as they are (ID.recalc_after_undo_push, the
depsgraph's update tags since the last undo step; members of a *Runtime type, such as a cache
the sequencer made; the sharing handles of shared arrays, memory addresses), the pointer values
(stand-ins numbered in the order of writing, so a block written and removed earlier renumbers
all later ones; shared arrays keep their memory address) and the order of some blocks.
canonical() clears the runtime fields, replaces each pointer by a digest of the block it points
to, and sorts the blocks; everything else is compared byte for byte.
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


def _runtime_ranges(fields: dict, sizes: dict, struct_name: str, cache: dict) -> list:
    """(offset, size) of the runtime members of a struct, nested structs included."""
    if struct_name in cache:
        return cache[struct_name]
    ranges, offset = [], 0
    for kind, name in fields.get(struct_name, []):
        pointer = name.startswith(("*", "(*"))
        size = 8 if pointer else sizes[kind]
        count = 1
        for extent in re.findall(r"\[(\d+)\]", name):
            count *= int(extent)
        # Runtime members, and the sharing handles of shared arrays (memory addresses).
        if name.lstrip("*_") == "runtime" or kind.endswith(("Runtime", "SharingInfoHandle")) or \
                name == "recalc_after_undo_push":
            ranges.append((offset, size * count))
        elif not pointer and kind in fields:
            inner = _runtime_ranges(fields, sizes, kind, cache)
            ranges += [(offset + k * size + at, n) for k in range(count) for at, n in inner]
        offset += size * count
    cache[struct_name] = ranges
    return ranges


def canonical(data: bytes) -> list:
    """The blocks, sorted, with runtime members cleared and each pointer replaced by a digest of
    the block it points to (its type and bytes, its own pointers zeroed): equal for two saves of
    the same data, whatever order or addresses Blender wrote them in."""
    items = blocks(data)
    order, fields, sizes = _sdna(next(body for code, *_, body in items if code == "DNA1"))
    cache: dict = {}
    base = max((old >> 32 for _, _, old, _, _ in items if old), key=[old >> 32 for *_, old, _, _ in items].count)
    targets = {old for _, _, old, _, _ in items if old}
    cleared = []
    for code, sdna, old, count, body in items:
        body = bytearray(body)
        kind = order[sdna] if sdna < len(order) else str(sdna)
        if code not in {"DNA1", "TEST", "REND", "ENDB"}:
            stride = sizes.get(kind, 0)
            for k in range(count if stride and stride * count == len(body) else 0):
                for at, n in _runtime_ranges(fields, sizes, kind, cache):
                    body[k * stride + at:k * stride + at + n] = bytes(n)
        pointers = []
        if code not in {"DNA1", "TEST"}:
            for at in range(0, len(body) - 7, 8):
                word = int.from_bytes(body[at:at + 8], "little")
                if word in targets or word >> 32 == base:
                    pointers.append((at, word))
                    body[at:at + 8] = bytes(8)
        cleared.append((code, kind, old, count, bytes(body), pointers))
    digest = {old: hashlib.sha1(f"{code}{kind}{count}".encode() + body).digest()[:8]
              for code, kind, old, count, body, _ in cleared if old}
    out = []
    for code, kind, old, count, body, pointers in cleared:
        body = bytearray(body)
        for at, word in pointers:
            body[at:at + 8] = digest.get(word, b"loose\0\0\0")
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
