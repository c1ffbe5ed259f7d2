"""Solutions on disk: knots, degrees and coefficients of every surface's radiance splines and the
settings used, in one numpy .npz file. Loading gives back bit-identical splines."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from . import _core

FORMAT = "bsgi-solution-1"


def spline_to_arrays(spline: _core.TensorSpline) -> dict:
    """A spline as plain arrays: 'knots<k>' per axis, 'degrees', 'coefficients' (shape n_0..n_{D-1}, channels)."""
    out = {f"knots{k}": np.array(axis.knots, np.float64) for k, axis in enumerate(spline.axes)}
    out["degrees"] = np.array([axis.degree for axis in spline.axes], np.int64)
    out["coefficients"] = np.array(spline.coefficients, np.float64)
    return out


def spline_from_arrays(arrays) -> _core.TensorSpline:
    """Inverse of spline_to_arrays (any mapping of name -> array-like)."""
    degrees = [int(d) for d in np.asarray(arrays["degrees"])]
    axes = [_core.KnotVector(np.asarray(arrays[f"knots{k}"], np.float64), d) for k, d in enumerate(degrees)]
    coefficients = np.asarray(arrays["coefficients"], np.float64)
    spline = _core.TensorSpline(axes, coefficients.shape[-1])
    spline.coefficients = coefficients.reshape(spline.coefficients.shape)
    return spline


def settings_to_dict(settings: _core.SolverSettings) -> dict:
    return {k: getattr(settings, k) for k in dir(settings) if not k.startswith("_") and not callable(getattr(settings, k))}


def settings_from_dict(values: dict) -> _core.SolverSettings:
    settings = _core.SolverSettings()
    for k, v in values.items():
        if hasattr(settings, k):
            setattr(settings, k, v)
    return settings


@dataclass
class StoredSolution:
    """What a solution file holds: per surface its radiance (None for pure emitters), as the
    upper-hemisphere spline (`radiance`) and as the whole SurfaceRadiance (`surfaces`: kind,
    disc radius, the back side's splines where it was solved: transmitting surfaces and opaque ones
    lit from behind; files from before two-sided surfaces load with the back sides they had; the
    albedo and emission textures of textured surfaces)."""

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
    arrays, kinds, radii, two_sided = {}, [], [], []
    for i, entry in enumerate(radiance):
        two_sided.append(bool(entry.two_sided_emission) if isinstance(entry, _core.SurfaceRadiance) else False)
        if entry is None:
            kinds.append(None)
            radii.append(None)
            continue
        surface = entry if isinstance(entry, _core.SurfaceRadiance) else None
        upper = surface.upper if surface else entry
        kinds.append(surface.kind if surface else ("glossy" if upper.dims == 4 else "diffuse"))
        radii.append(surface.disc_radius if surface else None)
        sides = {"upper": upper, "lower": surface.lower if surface else None,
                 "diffuse": surface.diffuse if surface else None,
                 "lower_diffuse": surface.lower_diffuse if surface else None}
        for side, spline in sides.items():
            if spline is not None:
                for key, value in spline_to_arrays(spline).items():
                    arrays[f"surface{i}/{side}/{key}"] = value
        for texture in ("albedo", "emission"):  # textured surfaces: float32 images over (u, v)
            image = getattr(surface, texture) if surface else None
            if image is not None:
                arrays[f"surface{i}/{texture}"] = image
    meta = {"format": FORMAT, "names": list(names), "settings": settings_to_dict(settings),
            "stats": dict(stats or {}), "solved": [k is not None for k in kinds], "kinds": kinds, "disc_radii": radii,
            "two_sided_emission": two_sided}
    with open(path, "wb") as f:
        np.savez_compressed(f, meta=np.frombuffer(json.dumps(meta).encode(), np.uint8), **arrays)


def load_solution(path) -> StoredSolution:
    """Read a file written by save_solution."""
    with np.load(path) as data:
        meta = json.loads(bytes(data["meta"]).decode())
        if meta.get("format") != FORMAT:
            raise ValueError(f"{path}: not a bsgi solution file (format {meta.get('format')!r})")
        radiance, surfaces = [], []
        two_sided = meta.get("two_sided_emission")  # absent in files from before two-sided emission
        for i, solved in enumerate(meta["solved"]):
            if not solved:
                radiance.append(None)
                surfaces.append(None)
                continue
            sides = {}
            for side in ("upper", "lower", "diffuse", "lower_diffuse"):
                prefix = f"surface{i}/{side}/"
                found = {k[len(prefix):]: data[k] for k in data.files if k.startswith(prefix)}
                sides[side] = spline_from_arrays(found) if found else None
            radiance.append(sides["upper"])
            radius = meta["disc_radii"][i]
            textures = {t: data[f"surface{i}/{t}"] if f"surface{i}/{t}" in data.files else None
                        for t in ("albedo", "emission")}
            surfaces.append(_core.SurfaceRadiance(meta["kinds"][i], radius if radius is not None else 1.0,
                                                  sides["upper"], sides["lower"], sides["diffuse"],
                                                  sides["lower_diffuse"], **textures,
                                                  two_sided_emission=bool(two_sided[i]) if two_sided else False))
    return StoredSolution(radiance, surfaces, meta["names"], settings_from_dict(meta["settings"]), meta["stats"])
