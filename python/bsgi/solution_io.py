"""Solutions on disk: knots, degrees and coefficients of every surface's radiance splines and the
settings used, in one numpy .npz file. Loading gives back bit-identical splines."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from . import _core
from .rebuildable import settings_fields, settings_from
from .split import Band, SplitRadiance

FORMAT = "bsgi-solution-1"


def spline_to_arrays(spline: _core.TensorSpline) -> dict:
    """A spline as plain arrays: 'knots<k>' per axis, 'degrees', 'coefficients' (shape n_0..n_{D-1}, channels)."""
    out = {f"knots{k}": np.array(axis.knots, np.float64) for k, axis in enumerate(spline.axes)}
    out["degrees"] = np.array([axis.degree for axis in spline.axes], np.int64)
    out["coefficients"] = np.array(spline.coefficients, np.float64)
    return out


def spline_from_arrays(arrays) -> _core.TensorSpline:
    """Inverse of spline_to_arrays (any mapping of name -> array-like)."""
    degrees = np.asarray(arrays["degrees"])
    knots = [np.asarray(arrays[f"knots{k}"], np.float64) for k in range(degrees.size)]
    if degrees.ndim != 1 or any(k.ndim != 1 for k in knots):
        raise ValueError(f"spline arrays: degrees of shape {degrees.shape} and knots of shapes "
                         f"{[k.shape for k in knots]}, not one degree and one knot row per axis")
    axes = [_core.KnotVector(k, int(d)) for k, d in zip(knots, degrees)]
    coefficients = np.asarray(arrays["coefficients"], np.float64)
    if coefficients.ndim != len(axes) + 1:
        raise ValueError(f"spline arrays: coefficients of shape {coefficients.shape} for {len(axes)} axes and channels")
    spline = _core.TensorSpline(axes, coefficients.shape[-1])
    if coefficients.shape != tuple(spline.shape):
        raise ValueError(f"spline arrays: coefficients of shape {coefficients.shape}, the knots give {tuple(spline.shape)}")
    spline.coefficients = coefficients
    return spline


def settings_from_dict(values: dict) -> _core.SolverSettings:
    """A file's settings: the fields this version has (a file of another version may name others)."""
    return settings_from({k: v for k, v in values.items() if hasattr(_core.SolverSettings, k)})


# A SurfaceRadiance's textures (a normal map's bumped normals among them), and the base of an
# albedo texture under a layered coat (the coat's directional albedo and the albedo its S took its
# share at; absent in older files).
COAT_AND_TEXTURES = ("albedo", "emission", "specular", "coat_share", "coat_albedo", "normals")


@dataclass
class StoredSolution:
    """What a solution file holds: per surface its radiance (None for pure emitters), as the
    upper-hemisphere spline (`radiance`) and as the whole SurfaceRadiance (`surfaces`: kind,
    disc radius, the back side's splines where it was solved: transmitting surfaces and opaque ones
    lit from behind; files from before two-sided surfaces load with the back sides they had; the
    albedo, emission and specular textures of textured surfaces, with a textured GGX f0 the
    splines at f0 = 0, with an albedo texture under a layered coat its base's coat_share and
    coat_albedo)."""

    radiance: list
    surfaces: list
    names: list
    settings: _core.SolverSettings
    stats: dict = field(default_factory=dict)


def save_solution(path, radiance: Sequence, names: Sequence[str], settings: _core.SolverSettings,
                  stats: Optional[dict] = None) -> None:
    """Write a solution: ``solution.surfaces`` (everything) or ``solution.radiance`` (the upper
    splines, read back as diffuse or glossy by their dimension), with the surfaces' names."""
    if len(radiance) != len(names):
        raise ValueError(f"save_solution: {len(radiance)} splines but {len(names)} names")
    arrays, kinds, radii, two_sided, pieces = {}, [], [], [], []
    for i, entry in enumerate(radiance):
        two_sided.append(bool(entry.two_sided_emission) if isinstance(entry, (_core.SurfaceRadiance, SplitRadiance)) else False)
        pieces.append(len(entry.pieces) if isinstance(entry, SplitRadiance) else 0)
        if entry is None:
            kinds.append(None)
            radii.append(None)
            continue
        surface = entry if isinstance(entry, (_core.SurfaceRadiance, SplitRadiance)) else None
        kinds.append(surface.kind if surface else ("glossy" if entry.dims == 4 else "diffuse"))
        radii.append(surface.disc_radius if surface else None)
        if isinstance(entry, SplitRadiance):  # a surface solved in pieces (bsgi.split): each piece and its band
            for k, (band, piece) in enumerate(zip(entry.bands, entry.pieces)):
                arrays.update(_surface_arrays(f"surface{i}/piece{k}/", piece))
                arrays[f"surface{i}/band{k}/range"] = np.array([band.t0, band.t1])
                arrays[f"surface{i}/band{k}/lower"] = np.asarray(band.lower, np.float64)
                arrays[f"surface{i}/band{k}/upper"] = np.asarray(band.upper, np.float64)
                arrays[f"surface{i}/band{k}/along_v"] = np.array([band.along_v])
        else:
            arrays.update(_surface_arrays(f"surface{i}/", entry))
    meta = {"format": FORMAT, "names": list(names), "settings": settings_fields(settings),
            "stats": dict(stats or {}), "solved": [k is not None for k in kinds], "kinds": kinds, "disc_radii": radii,
            "two_sided_emission": two_sided, "pieces": pieces}
    with open(path, "wb") as f:
        np.savez_compressed(f, meta=np.frombuffer(json.dumps(meta).encode(), np.uint8), **arrays)


def _surface_arrays(prefix: str, entry) -> dict:
    """One surface's splines and textures under `prefix` (a SurfaceRadiance, or an upper spline alone)."""
    surface = entry if isinstance(entry, _core.SurfaceRadiance) else None
    sides = {"upper": surface.upper if surface else entry, "lower": surface.lower if surface else None,
             "diffuse": surface.diffuse if surface else None,
             "lower_diffuse": surface.lower_diffuse if surface else None,
             "tint_zero": surface.tint_zero if surface else None,
             "lower_tint_zero": surface.lower_tint_zero if surface else None}
    arrays = {}
    for side, spline in sides.items():
        if spline is not None:
            for key, value in spline_to_arrays(spline).items():
                arrays[f"{prefix}{side}/{key}"] = value
    for texture in COAT_AND_TEXTURES:  # textured surfaces: float32 images over (u, v); a coat's base
        value = getattr(surface, texture) if surface else None
        if value is not None:
            arrays[f"{prefix}{texture}"] = value
    return arrays


def load_solution(path) -> StoredSolution:
    """Read a file written by save_solution. Anything else (another file, a truncated or corrupted
    one, another format version, splines that are not valid) raises ValueError naming the file
    and the problem; a file that cannot be opened raises the OSError of opening it."""
    try:
        return _read_solution(path)
    except (FileNotFoundError, IsADirectoryError, PermissionError):
        raise
    except _Refused as error:
        raise ValueError(f"{path}: {error}") from None
    except Exception as error:  # zip, zlib, npy, JSON or shape errors of a damaged file
        raise ValueError(f"{path}: not a readable bsgi solution file ({type(error).__name__}: {error})") from error


class _Refused(Exception):
    """A problem of a readable file's content, said in the file's terms."""


def _read_solution(path) -> StoredSolution:
    with np.load(path, allow_pickle=False) as data:
        if "meta" not in data.files:
            raise _Refused("not a bsgi solution file (no 'meta' record)")
        meta = json.loads(bytes(data["meta"]).decode())
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            found = meta.get("format") if isinstance(meta, dict) else None
            raise _Refused(f"not a bsgi solution file of this version (format {found!r}, expected {FORMAT!r})")
        names, solved = meta.get("names"), meta.get("solved")
        kinds, radii = meta.get("kinds"), meta.get("disc_radii")
        if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
            raise _Refused("'names' must be a list of surface names")
        for key, value in (("solved", solved), ("kinds", kinds), ("disc_radii", radii)):
            if not (isinstance(value, list) and len(value) == len(names)):
                raise _Refused(f"'{key}' must be a list of one entry per surface ({len(names)})")
        if not isinstance(meta.get("settings", {}), dict) or not isinstance(meta.get("stats", {}), dict):
            raise _Refused("'settings' and 'stats' must be records")
        radiance, surfaces = [], []
        two_sided = meta.get("two_sided_emission")  # absent in files from before two-sided emission
        if two_sided is not None and not (isinstance(two_sided, list) and len(two_sided) == len(names)):
            raise _Refused(f"'two_sided_emission' must be a list of one entry per surface ({len(names)})")
        pieces = meta.get("pieces") or [0] * len(names)  # absent in files from before split surfaces
        if not (isinstance(pieces, list) and len(pieces) == len(names) and all(isinstance(n, int) for n in pieces)):
            raise _Refused(f"'pieces' must be a list of one count per surface ({len(names)})")
        for i, is_solved in enumerate(solved):
            if not is_solved:
                radiance.append(None)
                surfaces.append(None)
                continue
            try:
                emits_back = bool(two_sided[i]) if two_sided else False
                surface = (_read_split(data, i, pieces[i], kinds[i], radii[i]) if pieces[i]
                           else _read_surface(data, f"surface{i}/", kinds[i], radii[i], emits_back))
            except _Refused as error:
                raise _Refused(f"surface '{names[i]}': {error}") from None
            except ValueError as error:  # the core's refusal of the knots, shapes or textures
                raise _Refused(f"surface '{names[i]}': {error}") from None
            radiance.append(surface.upper)
            surfaces.append(surface)
        settings = settings_from_dict(meta.get("settings", {}))
    return StoredSolution(radiance, surfaces, names, settings, meta.get("stats", {}))


def _read_split(data, i: int, count: int, kind, radius) -> SplitRadiance:
    bands, pieces = [], []
    for k in range(count):
        prefix = f"surface{i}/band{k}/"
        if any(prefix + key not in data.files for key in ("range", "lower", "upper", "along_v")):
            raise _Refused(f"piece {k} has no band (range, lower, upper, along_v)")
        t0, t1 = (float(t) for t in np.asarray(data[prefix + "range"], np.float64))
        bands.append(Band(t0, t1, np.asarray(data[prefix + "lower"], np.float64), np.asarray(data[prefix + "upper"], np.float64),
                          bool(np.asarray(data[prefix + "along_v"])[0])))
        pieces.append(_read_surface(data, f"surface{i}/piece{k}/", kind, radius, False))
    return SplitRadiance(bands, pieces)


def _read_surface(data, root: str, kind, radius, two_sided_emission: bool) -> _core.SurfaceRadiance:
    sides = {}
    for side in ("upper", "lower", "diffuse", "lower_diffuse", "tint_zero", "lower_tint_zero"):
        prefix = f"{root}{side}/"
        found = {k[len(prefix):]: data[k] for k in data.files if k.startswith(prefix)}
        if not found:
            sides[side] = None
            continue
        for key in ("degrees", "coefficients"):
            if key not in found:
                raise _Refused(f"{side} spline has no '{key}'")
        degrees = np.asarray(found["degrees"])
        if degrees.ndim != 1 or not np.issubdtype(degrees.dtype, np.integer):
            raise _Refused(f"{side} spline: 'degrees' must be a list of integers")
        if any(f"knots{k}" not in found for k in range(len(degrees))):
            raise _Refused(f"{side} spline: needs knots of each of its {len(degrees)} axes")
        coefficients = np.asarray(found["coefficients"])
        if coefficients.dtype.kind != "f" or not np.isfinite(coefficients).all():
            raise _Refused(f"{side} spline: coefficients must be finite numbers")
        sides[side] = spline_from_arrays(found)
    if sides["upper"] is None:
        raise _Refused("solved but no upper spline")
    if not (radius is None or (isinstance(radius, (int, float)) and not isinstance(radius, bool))):
        raise _Refused(f"disc radius {radius!r} is not a number")
    if not isinstance(kind, str):
        raise _Refused(f"kind {kind!r} is not a name")
    textures = {t: data[f"{root}{t}"] if f"{root}{t}" in data.files else None for t in COAT_AND_TEXTURES}
    return _core.SurfaceRadiance(kind, radius if radius is not None else 1.0, sides["upper"], sides["lower"],
                                 sides["diffuse"], sides["lower_diffuse"], **textures,
                                 two_sided_emission=two_sided_emission, tint_zero=sides["tint_zero"],
                                 lower_tint_zero=sides["lower_tint_zero"])
