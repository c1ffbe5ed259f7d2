"""Surfaces split along the lines where other surfaces pass through them (paper section 5.1).

Where one surface passes through another (a vase standing in a floor that rises under it, a metal
sheet pushed into a cove), the light on the other is lit on one side of the line and in the
first's shadow, or inside it, on the other: a jump that no spline over the whole surface follows.
On the Bézier patches' cove, 35 of 2,693 compared pairs within 5 cm of two such lines carried 86%
of the final preset's squared error. Split along the lines, each piece's spline ends at the jump.

Found per NURBS surface that a solve reflects diffusely (2D splines; a glossy surface's pieces
would need their own frames in the bake): the segments between neighbouring points of a grid over
its domain, cast against the other surfaces, cross them where another surface passes through.
Along each parameter, the columns crossed form runs; a run crossed the same number of times in
(nearly) every column is a band whose lines are graphs over that parameter, and the surface is cut
into bands between them (SplitPiece) plus the whole columns around. A run whose count changes (a
line turning back, lines crossing) is left whole. The direction with the fewer pieces wins.

The solve runs on the split scene; its solution answers for the scene it was given: a split
surface's radiance routes each (u, v) to its piece (SplitRadiance), its report merges its pieces'.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from . import _core
from .rebuildable import SCENE_CALLS, Scene, SplitPiece

# Grid steps per parameter for finding crossings: a line shorter than two steps is not split along.
CROSSING_STEPS = 256
# A run is one band if at least this share of its columns cross it equally often (a segment
# through a seam between two patches of the other surface can miss it; those columns are
# interpolated from their neighbours).
CLEAN_SHARE = 0.9
# Segments ignore hits this close to their ends (in their own length): a neighbour meeting the
# surface along its edge is not a line through it.
END_MARGIN = 1e-4
# Empty columns bridged inside a line (_bridged).
MAX_GAP = 2
# Lines spanning less of the parameter they run along are not split along: each piece is a surface
# with its own coefficients (the fewest a surface gets, and more for the light's detail), so the
# small rings where a mug's handle enters its wall cost more than their jump's error: split there,
# the mug's preview took 12 times as long for 0.71% -> 0.68% (its final 23 times, for nothing).
# The Bézier patches' lines span 0.125 (the vase's foot in the cove) to 1.
SHORTEST_LINE = 0.08
SURFACE_CALLS = ("add_bilinear_patch", "add_triangle", "add_disk", "add_surface")


@dataclass
class Band:
    """One piece's place in its parent's domain (SplitPiece's arguments)."""

    t0: float
    t1: float
    lower: np.ndarray
    upper: np.ndarray
    along_v: bool


def crossings(surface, casters: tuple, along_v: bool, steps: int = CROSSING_STEPS) -> tuple:
    """(grid, columns): the grid of one parameter (u, or v along_v) and, per grid value, the sorted
    values of the other parameter where the segments along it cross another surface.

    casters: (chords, exact). The other surfaces' own triangles (chords) find which segments
    cross; the ray caster's exact surfaces then place the crossings. The exact caster alone
    misses some: its triangles stand off the surfaces by up to a few millimetres, so a segment
    that crosses a surface may meet its triangle only in the next segment, whose exact hit then
    lies behind its start."""
    chords, exact = casters
    g = np.linspace(0.0, 1.0, steps + 1)
    h = g[1] - g[0]
    t, w = np.meshgrid(g, g, indexing="ij")  # [column (along), point across]
    uv = np.stack([w, t] if along_v else [t, w], axis=-1).reshape(-1, 2)
    p = surface.evaluate(uv)["position"].reshape(steps + 1, steps + 1, 3)
    origins = np.ascontiguousarray(p[:, :-1].reshape(-1, 3))
    directions = np.ascontiguousarray((p[:, 1:] - p[:, :-1]).reshape(-1, 3))
    n = len(origins)
    hit = chords.closest_hit(origins, directions, np.full(n, END_MARGIN), np.full(n, 1 - END_MARGIN))
    crossed = np.nonzero(hit["surface"] >= 0)[0]
    at = g[:-1][crossed % steps] + hit["t"][crossed] * h
    # Placed on the exact surfaces: a ray along the chord from two segments before to two after.
    start = origins[crossed] - 2 * directions[crossed]
    placed = exact.closest_hit(np.ascontiguousarray(start), np.ascontiguousarray(directions[crossed]),
                               np.zeros(len(crossed)), np.full(len(crossed), 5.0))
    good = (placed["surface"] >= 0) & (np.abs(placed["t"] - 2 - hit["t"][crossed]) < 2)
    at[good] = g[:-1][crossed[good] % steps] + (placed["t"][good] - 2) * h
    columns = [[] for _ in range(steps + 1)]
    for row, value in zip(crossed // steps, at):
        columns[row].append(value)
    return g, [np.sort(np.array(c)) for c in columns]


def _chords(surface):
    """A surface's own triangles (its tessellation, not stood off) as a mesh for crossing tests."""
    t = surface.tessellate()
    uvs = np.clip(t["uvs"][t["triangles"]].reshape(-1, 2).astype(np.float64), 0.0, 1.0)
    return _core.MeshChart(surface.name, t["positions"], t["triangles"].astype(np.uint32), uvs)


def bands(grid: np.ndarray, columns: list, along_v: bool) -> Optional[list]:
    """The pieces (Bands) cutting the domain along the lines, or None if a run is not clean; []
    when nothing crosses."""
    columns = _bridged(grid, columns)
    counts = np.array([len(c) for c in columns])
    out, edge, i = [], 0.0, 0
    whole = dict(lower=np.array([0.0]), upper=np.array([1.0]), along_v=along_v)
    while i < len(grid):
        if counts[i] == 0:
            i += 1
            continue
        j = i
        while j + 1 < len(grid) and counts[j + 1] > 0:
            j += 1
        k = int(np.bincount(counts[i:j + 1]).argmax())
        good = [c for c in range(i, j + 1) if counts[c] == k]
        if len(good) < CLEAN_SHARE * (j + 1 - i):
            return None
        if grid[j] - grid[i] >= SHORTEST_LINE and len(good) >= 2:
            lines = np.array([[np.interp(grid[c], grid[good], [columns[q][m] for q in good]) for m in range(k)]
                              for c in range(i, j + 1)])
            t0, t1 = grid[i], grid[j]
            if edge < t0:
                out.append(Band(edge, t0, **whole))
            layers = [np.zeros(len(lines))] + [lines[:, m] for m in range(k)] + [np.ones(len(lines))]
            out += [Band(t0, t1, layers[m], layers[m + 1], along_v) for m in range(k + 1)]
            edge = t1
        i = j + 1
    if out and edge < 1:
        out.append(Band(edge, 1.0, **whole))
    return out


def _bridged(grid: np.ndarray, columns: list, widest: int = MAX_GAP) -> list:
    """Columns with no crossing between two crossed equally often, at most `widest` of them, take
    the values between their neighbours': a line through a grid point touches its two segments
    at their ends only, which the margin leaves out."""
    columns = list(columns)
    counts = [len(c) for c in columns]
    c = 1
    while c < len(columns) - 1:
        if counts[c] == 0 and counts[c - 1] > 0:
            end = c
            while end < len(columns) and counts[end] == 0:
                end += 1
            if end < len(columns) and end - c <= widest and counts[end] == counts[c - 1]:
                for k in range(c, end):
                    f = (grid[k] - grid[c - 1]) / (grid[end] - grid[c - 1])
                    columns[k] = (1 - f) * columns[c - 1] + f * columns[end]
            c = end
        c += 1
    return columns


def plan(surface, casters: tuple, steps: int = CROSSING_STEPS) -> list:
    """The Bands of the direction with the fewer pieces ([] when none is clean or nothing crosses)."""
    options = [b for along_v in (False, True) if (b := bands(*crossings(surface, casters, along_v, steps), along_v))]
    return min(options, key=len) if options else []


def _surface_of(call_args: tuple, call_kwargs: dict):
    return call_args[0] if call_args else call_kwargs.get("surface")


def _diffuse(call_args: tuple, call_kwargs: dict) -> bool:
    """An add_surface call's surface is a diffuse receiver that emits nothing (2D splines)."""
    names = ("surface", "albedo", "emission", "receiver", "occluder", "bsdf")
    given = dict(zip(names, call_args)) | call_kwargs
    bsdf = given.get("bsdf")
    return (given.get("receiver", True) and given.get("thin_glass") is None
            and not np.any(np.asarray(given["emission"], float) > 0)
            and (bsdf is None or type(bsdf).__name__ == "Lambert"))


@dataclass
class Split:
    """A scene with some surfaces split: `scene` is solved; pieces[i] lists surface i's
    (index in `scene`, Band); index[i] is surface i's index in `scene` where it is whole."""

    scene: Any
    pieces: dict
    index: list

    def sides(self, sides: Optional[list]) -> Optional[list]:
        """Sides probed on the original scene, for the split one: each piece its parent's."""
        if sides is None:
            return None
        out = [None] * len(self.scene)
        for i, side in enumerate(sides):
            for j in ([j for j, _ in self.pieces[i]] if i in self.pieces else [self.index[i]]):
                out[j] = side
        return out

    def solution(self, solution) -> "SplitSolution":
        return SplitSolution(self, solution)


def split_scene(scene) -> Optional[Split]:
    """The scene with its diffuse NURBS surfaces split along the lines other surfaces cross them
    at, or None when none is (or the scene does not keep its calls: a compiled scene)."""
    calls = getattr(scene, "_bsgi_calls", None)
    if calls is None:
        return None
    textured = {args[0] for name, args, _ in calls if name.startswith("set_") and name.endswith("_texture")}
    candidates, index = [], 0
    for name, args, kwargs in calls:
        if name not in SURFACE_CALLS:
            continue
        if (name == "add_surface" and index not in textured and isinstance(_surface_of(args, kwargs), _core.NurbsSurface)
                and _diffuse(args, kwargs)):
            candidates.append(index)
        index += 1
    if not candidates:
        return None
    surfaces = [scene.surface(i) for i in range(len(scene))]
    chords = [_chords(s) for s in surfaces]
    plans = {}
    for i in candidates:
        casters = (_core.RayCaster([c for j, c in enumerate(chords) if j != i]),
                   _core.RayCaster([s for j, s in enumerate(surfaces) if j != i]))
        if b := plan(surfaces[i], casters):
            plans[i] = b
    if not plans:
        return None
    return _replay(calls, plans)


def _replay(calls: list, plans: dict) -> Split:
    split = Scene()
    pieces, index, old = {}, [], 0
    for name, args, kwargs in calls:
        if name.startswith("="):
            setattr(split, name[1:], args[0])
            continue
        method = getattr(split, name)
        if name in SURFACE_CALLS:
            if old in plans:
                parent = _surface_of(args, kwargs)
                rest_args, rest_kwargs = (args[1:], kwargs) if args else (args, {k: v for k, v in kwargs.items() if k != "surface"})
                n = len(plans[old])
                pieces[old] = [(method(SplitPiece(f"{parent.name} / piece {k + 1} of {n}", parent, b.t0, b.t1, b.lower, b.upper,
                                                  b.along_v), *rest_args, **rest_kwargs), b)
                               for k, b in enumerate(plans[old])]
                index.append(None)
            else:
                index.append(method(*args, **kwargs))
            old += 1
        elif name in SCENE_CALLS and name != "add_distant_light":
            # set_*(index, ...): a split surface's setting applies to each of its pieces.
            targets = [j for j, _ in pieces[args[0]]] if args[0] in pieces else [index[args[0]]]
            for j in targets:
                method(j, *args[1:], **kwargs)
        else:
            method(*args, **kwargs)
    return Split(split, pieces, index)


class SplitSpline:
    """A split surface's 2D spline over its parent's (u, v): each point read from its piece's."""

    dims = 2

    def __init__(self, bands: list, splines: list):
        self.bands, self.splines = bands, splines
        # Enough for an image to resolve the finest piece: its coefficients over its share of the domain.
        self.axes = [_Axis(max(math.ceil(s.axes[a].num_coeffs / _share(b, a)) for b, s in zip(bands, splines)),
                           splines[0].axes[a].degree) for a in (0, 1)]

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        return _by_piece(self.bands, points, self.channels, lambda k, ab, rows: self.splines[k].evaluate(ab))

    @property
    def channels(self) -> int:
        return self.splines[0].channels

    @property
    def coefficients(self) -> np.ndarray:
        """Every piece's coefficients, (total, channels): not a tensor, for checks over all of them."""
        return np.concatenate([np.asarray(s.coefficients).reshape(-1, s.channels) for s in self.splines])


@dataclass
class _Axis:
    num_coeffs: int
    degree: int


def _share(band: Band, axis: int) -> float:
    """The share of the parent's parameter `axis` (0: u) one piece spans (across: its mean width)."""
    along = 1 if band.along_v else 0
    if axis == along:
        return band.t1 - band.t0
    return max(float(np.mean(np.asarray(band.upper) - np.asarray(band.lower))), 1e-3)


def locate(bands: list, uv: np.ndarray) -> tuple:
    """Per (u, v) row: the piece holding it and its (a, b) there (the core's SplitPiece mapping).
    A point on a line belongs to the band listed first; one outside every band by rounding, to
    the nearest."""
    piece = np.full(len(uv), -1)
    ab = np.zeros_like(uv)
    gap = np.full(len(uv), np.inf)
    for k, b in enumerate(bands):
        mapped = _core.split_band_parameters(b.t0, b.t1, np.asarray(b.lower, float), np.asarray(b.upper, float),
                                             b.along_v, np.ascontiguousarray(uv, np.float64))
        outside = (np.maximum(-mapped, 0) + np.maximum(mapped - 1, 0)).sum(axis=1)
        better = outside < gap
        piece[better], ab[better], gap[better] = k, mapped[better], outside[better]
    return piece, np.clip(ab, 0.0, 1.0)


def _by_piece(bands: list, uv: np.ndarray, channels: int, evaluate) -> np.ndarray:
    """(N, channels): evaluate(k, (a, b) rows, their row mask) for the rows each piece k holds."""
    uv = np.asarray(uv, np.float64)
    out = np.zeros((len(uv), channels))
    piece, ab = locate(bands, uv[:, :2])
    for k in range(len(bands)):
        rows = piece == k
        if rows.any():
            out[rows] = evaluate(k, np.ascontiguousarray(ab[rows]), rows)
    return out


class SplitRadiance:
    """A split surface's radiance as a SurfaceRadiance of its own (u, v) (diffuse: 2D, no textures)."""

    kind = "diffuse"
    albedo = emission = specular = tint_zero = lower_tint_zero = diffuse = lower_diffuse = None
    two_sided_emission = False

    def __init__(self, bands: list, radiances: list):
        self.bands, self.pieces = bands, radiances
        self.disc_radius = radiances[0].disc_radius
        self.upper = SplitSpline(bands, [r.upper for r in radiances])
        lowers = [r.lower for r in radiances]
        self.lower = SplitSpline(bands, lowers) if all(s is not None for s in lowers) else None

    def evaluate(self, uv: np.ndarray, directions: np.ndarray) -> np.ndarray:
        directions = np.asarray(directions, np.float64)
        return _by_piece(self.bands, uv, 3, lambda k, ab, rows: self.pieces[k].evaluate(
            ab, np.ascontiguousarray(directions[rows])))


class SplitSolution:
    """A solution of the split scene answering for the scene it was split from: radiance,
    surfaces and reports per original surface; the rest (stats, refinement) the split solve's."""

    def __init__(self, split: Split, solution):
        self._split, self._solution = split, solution
        self.split = {i: len(p) for i, p in split.pieces.items()}  # original index -> its pieces
        self._surfaces = None

    def __getattr__(self, name: str):
        return getattr(self._solution, name)

    def _per_surface(self, values: list, merge) -> list:
        out = []
        for i, j in enumerate(self._split.index):
            if j is not None:
                out.append(values[j])
                continue
            parts = [values[k] for k, _ in self._split.pieces[i]]
            out.append(None if any(p is None for p in parts) else merge(i, parts))
        return out

    @property
    def surfaces(self) -> list:
        if self._surfaces is None:
            self._surfaces = self._per_surface(self._solution.surfaces,
                                               lambda i, parts: SplitRadiance([b for _, b in self._split.pieces[i]], parts))
        return list(self._surfaces)

    @property
    def radiance(self) -> list:
        return [None if r is None else r.upper for r in self.surfaces]

    @property
    def reports(self) -> list:
        """One per original surface, in the split solve's order (a split surface where its first
        piece's stood): its pieces' estimated errors merged (_merged_report)."""
        inner = self._solution.reports
        radiance = self._solution.radiance
        by_name = {r["name"]: r for r in inner}
        scene = self._split.scene
        parent_of, out = {}, []
        for i, pieces in self._split.pieces.items():
            for j, _ in pieces:
                parent_of[scene.name(j)] = i
        done = set()
        for r in inner:
            i = parent_of.get(r["name"])
            if i is None:
                out.append(r)
            elif i not in done:
                done.add(i)
                # Each piece weighs by its area and its light's mean square (its coefficients'):
                # the relative RMS error of the whole surface, where a dark piece's counts little.
                parts = [(scene.area(j) * _mean_square(radiance[j]), by_name[scene.name(j)])
                         for j, _ in self._split.pieces[i]]
                out.append(_merged_report(r["name"].rsplit(" / piece ", 1)[0], parts))
        return out


def _mean_square(spline) -> float:
    return 0.0 if spline is None else float(np.mean(np.square(spline.coefficients)))


def _merged_report(name: str, parts: list) -> dict:
    """Its pieces' reports as one: estimates as the RMS over the pieces that have one, by weight
    (a piece no light reaches, under the surface it is split from, has none)."""
    def rms(get) -> float:
        known = [(w, get(r)) for w, r in parts if math.isfinite(get(r))]
        total = sum(w for w, _ in known)
        return math.sqrt(sum(w * e * e for w, e in known) / total) if total > 0 else math.nan

    first = parts[0][1]
    largest = max((r for _, r in parts), key=lambda r: math.prod(r["shape"]) if r["shape"] else 0)
    return {"name": name, "representation": first["representation"], "shape": largest["shape"],
            "reason": f"split into {len(parts)} pieces along lines other surfaces pass through it; {largest['reason']}",
            "estimated_error": rms(lambda r: r["estimated_error"]),
            "error_parts": {k: rms(lambda r, k=k: r["error_parts"][k]) for k in first["error_parts"]},
            "pieces": len(parts)}
