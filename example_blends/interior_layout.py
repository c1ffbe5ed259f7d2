"""The layout of the furnished interior (issue 16's benchmark scene), with no Blender in it: a
reading room whose object count is a parameter. Shelf units full of books stand in rows, tables
with four chairs each stand by a window in the wall x = +length/2 (a sun and a sky light come in
through it), and metal balls lie on the tables. Used by make_furnished_interior.py (a .blend) and
bench/interior_core.py (the same boxes straight into a bsgi.Scene, for counts Blender is slow at).

Every piece is an axis-aligned box or a ball: Box(centre, size, material), Ball(centre, radius,
material). An object is a list of pieces (a chair is seat, back and four legs); the room is one
object whose walls are seen from inside.
"""
from __future__ import annotations

import math
import pathlib
import random
import sys
from dataclasses import dataclass, field

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import shapes  # noqa: E402

HEIGHT = 3.0
SHELF_UNIT = (1.0, 0.3, 2.0)  # width (x), depth (y), height
SHELF_BOARDS = (0.04, 0.52, 1.0, 1.48)  # heights of the boards books stand on
BOOKS_PER_BOARD = 20
TABLE = (1.2, 0.8, 0.74)
WINDOW_HEIGHTS = (0.9, 2.4)  # sill and lintel

# Name -> (linear RGB, metallic, roughness): a few book covers, wood, plaster, metal.
MATERIALS = {
    "plaster": ((0.75, 0.73, 0.7), 0.0, 1.0),
    "floor": ((0.35, 0.25, 0.18), 0.0, 1.0),
    "wood": ((0.45, 0.3, 0.18), 0.0, 1.0),
    "metal": ((0.9, 0.85, 0.75), 1.0, 0.3),
    "book red": ((0.5, 0.08, 0.06), 0.0, 1.0),
    "book green": ((0.08, 0.3, 0.12), 0.0, 1.0),
    "book blue": ((0.08, 0.12, 0.4), 0.0, 1.0),
    "book cream": ((0.7, 0.65, 0.5), 0.0, 1.0),
}
BOOK_MATERIALS = [name for name in MATERIALS if name.startswith("book")]


@dataclass
class Box:
    centre: tuple
    size: tuple
    material: str


@dataclass
class Ball:
    centre: tuple
    radius: float
    material: str


@dataclass
class Thing:
    name: str
    pieces: list = field(default_factory=list)


@dataclass
class Interior:
    length: float  # x: the window wall is at x = +length / 2
    width: float  # y
    things: list
    window: tuple  # (y0, y1, z0, z1) in the wall x = +length / 2
    sun_direction: tuple  # towards the sun
    counts: dict


def _shelf_frame(x, y, name):
    w, d, h = SHELF_UNIT
    t = 0.02
    pieces = [Box((x - w / 2 + t / 2, y, h / 2), (t, d, h), "wood"), Box((x + w / 2 - t / 2, y, h / 2), (t, d, h), "wood"),
              Box((x, y + d / 2 - t / 2, h / 2), (w - 2 * t, t, h), "wood")]
    pieces += [Box((x, y, z - t / 2), (w - 2 * t, d - t, t), "wood") for z in SHELF_BOARDS]
    return Thing(name, pieces)


def _books(x, y, count, rng, first):
    """count books on the unit's boards, left to right, board after board."""
    w, d, _ = SHELF_UNIT
    books = []
    for board in SHELF_BOARDS:
        left = x - w / 2 + 0.03
        for _ in range(BOOKS_PER_BOARD):
            if len(books) == count:
                return books
            thick, tall, deep = rng.uniform(0.025, 0.045), rng.uniform(0.18, 0.3), rng.uniform(0.15, 0.22)
            books.append(Thing(f"Book {first + len(books)}",
                               [Box((left + thick / 2, y + d / 2 - 0.02 - deep / 2, board + tall / 2), (thick, deep, tall),
                                    rng.choice(BOOK_MATERIALS))]))
            left += thick + 0.002
    return books


def _table_group(x, y, k):
    tw, td, th = TABLE
    leg = 0.05
    top = Box((x, y, th - 0.02), (tw, td, 0.04), "wood")
    legs = [Box((x + sx * (tw / 2 - leg), y + sy * (td / 2 - leg), (th - 0.04) / 2), (leg, leg, th - 0.04), "wood")
            for sx in (-1, 1) for sy in (-1, 1)]
    things = [Thing(f"Table {k}", [top] + legs)]
    for c, (cx, cy, back) in enumerate([(x - 0.35, y - 0.65, -1), (x + 0.35, y - 0.65, -1),
                                         (x - 0.35, y + 0.65, 1), (x + 0.35, y + 0.65, 1)]):
        seat = Box((cx, cy, 0.45), (0.44, 0.44, 0.04), "wood")
        chair_legs = [Box((cx + sx * 0.19, cy + sy * 0.19, 0.215), (0.04, 0.04, 0.43), "wood") for sx in (-1, 1) for sy in (-1, 1)]
        rest = Box((cx, cy + back * 0.2, 0.7), (0.44, 0.04, 0.46), "wood")
        things.append(Thing(f"Chair {k}.{c}", [seat, rest] + chair_legs))
    return things


def furnished_interior(objects: int, seed: int = 16) -> Interior:
    """A reading room of exactly `objects` objects (at least 8): one room, table groups (a table
    and four chairs) with a metal ball on each, and shelf units (a frame and up to 80 books) for
    the rest. The room grows with the number of shelf units, keeping their spacing."""
    if objects < 8:
        raise ValueError(f"furnished interior: {objects} objects is too few (at least 8: room, table, chairs, ball)")
    rng = random.Random(seed)
    groups = max(1, objects // 250)
    rest = objects - 1 - 6 * groups  # the room; per group a table, four chairs and a ball
    units = max(1, math.ceil(rest / (1 + BOOKS_PER_BOARD * len(SHELF_BOARDS)))) if rest > 0 else 0
    books = rest - units
    # Shelf units in rows across the room (y), rows along x, 1.6 m apart; tables by the window.
    per_row = max(2, math.ceil(math.sqrt(units * 2)))
    rows = math.ceil(units / per_row) if units else 0
    width = max(6.0, per_row * (SHELF_UNIT[0] + 0.05) + 2.0)
    table_rows = math.ceil(groups / max(1, int((width - 1.0) // 2.2)))
    length = max(6.0, rows * 1.6 + table_rows * 2.2 + 3.0)
    things = [Thing("Room", [])]  # the room's walls come from room_quads()
    x0 = -length / 2 + 1.0
    for u in range(units):
        row, col = divmod(u, per_row)
        x = x0 + row * 1.6
        y = -width / 2 + 1.0 + col * (SHELF_UNIT[0] + 0.05) + SHELF_UNIT[0] / 2
        things.append(_shelf_frame(x, y, f"Shelf {u}"))
        count = books // units + (1 if u < books % units else 0)
        things += _books(x, y, count, rng, first=sum(t.name.startswith("Book") for t in things))
    per_table_row = max(1, int((width - 1.0) // 2.2))
    for g in range(groups):
        r, c = divmod(g, per_table_row)
        x = length / 2 - 1.6 - r * 2.2
        y = -width / 2 + 1.5 + c * 2.2
        things += _table_group(x, y, g)
        things.append(Thing(f"Ball {g}", [Ball((x + 0.2, y - 0.1, TABLE[2] + 0.12), 0.12, "metal")]))
    assert len(things) == objects, (len(things), objects)
    elevation, azimuth = math.radians(35), math.radians(-20)
    sun = (math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation))
    window = (-min(1.5, width / 4), min(1.5, width / 4), *WINDOW_HEIGHTS)
    counts = {"books": books, "shelf units": units, "table groups": groups}
    return Interior(length, width, things, window, sun, counts)


def room_quads(interior: Interior) -> list:
    """The room's quads, corners counter-clockwise seen from inside (normals into the room): floor,
    ceiling, three walls, and the window wall around its opening."""
    lx, wy, h = interior.length / 2, interior.width / 2, HEIGHT
    y0, y1, z0, z1 = interior.window
    return [
        ("floor", [(-lx, -wy, 0), (lx, -wy, 0), (lx, wy, 0), (-lx, wy, 0)]),
        ("plaster", [(-lx, -wy, h), (-lx, wy, h), (lx, wy, h), (lx, -wy, h)]),
        ("plaster", [(-lx, -wy, 0), (-lx, -wy, h), (lx, -wy, h), (lx, -wy, 0)]),
        ("plaster", [(lx, wy, 0), (lx, wy, h), (-lx, wy, h), (-lx, wy, 0)]),
        ("plaster", [(-lx, wy, 0), (-lx, wy, h), (-lx, -wy, h), (-lx, -wy, 0)]),
        ("plaster", [(lx, -wy, 0), (lx, -wy, z0), (lx, wy, z0), (lx, wy, 0)]),
        ("plaster", [(lx, -wy, z1), (lx, -wy, h), (lx, wy, h), (lx, wy, z1)]),
        ("plaster", [(lx, -wy, z0), (lx, -wy, z1), (lx, y0, z1), (lx, y0, z0)]),
        ("plaster", [(lx, y1, z0), (lx, y1, z1), (lx, wy, z1), (lx, wy, z0)]),
    ]


def box_quads(box: Box) -> list:
    """The six faces of a box, outward normals."""
    (cx, cy, cz), (sx, sy, sz) = box.centre, box.size
    return shapes.box_quads(cx, cy, sx, sy, sz, 0.0, z0=cz - sz / 2)
