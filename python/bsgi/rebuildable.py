"""Scenes that pickle, so that a solve's workers (bsgi.RayExecutor) can rebuild them.

The compiled scene does not expose everything it was built from (a BSDF's parameters, a mesh's
arrays), so each of these classes keeps the arguments it was built with, and the scene the calls
that built it; unpickling makes the same calls, which build the same scene bit for bit. Arrays
are copied when recorded: a caller may reuse its buffers.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import _core


def _kept(value: Any) -> Any:
    return np.array(value, copy=True) if isinstance(value, np.ndarray) else value


def _record(args: tuple, kwargs: dict) -> tuple:
    return tuple(_kept(a) for a in args), {k: _kept(v) for k, v in kwargs.items()}


def _rebuild(cls: type, args: tuple, kwargs: dict, calls: tuple = ()) -> Any:
    obj = cls(*args, **kwargs)
    for name, call_args, call_kwargs in calls:
        if name.startswith("="):
            setattr(obj, name[1:], call_args[0])
        else:
            getattr(obj, name)(*call_args, **call_kwargs)
    return obj


class _OfCompiledKind(type(_core.Scene)):
    """isinstance(x, bsgi.BilinearPatch) holds for the compiled class's objects too (the patches
    Scene.add_bilinear_patch makes, which the scene's own calls rebuild)."""

    def __instancecheck__(cls, obj: Any) -> bool:
        compiled = next(b for b in cls.__mro__ if b.__module__ == _core.__name__)
        return isinstance(obj, compiled)


class _Rebuildable(metaclass=_OfCompiledKind):
    """Keeps its constructor's arguments for pickle."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._bsgi_args = _record(args, kwargs)

    def __reduce__(self) -> tuple:
        return _rebuild, (type(self), *self._bsgi_args)


# Surfaces and BSDFs a scene takes (the analytic patches of Scene.add_* keep their corners in the call).
class NurbsSurface(_Rebuildable, _core.NurbsSurface):
    __doc__ = _core.NurbsSurface.__doc__


class MeshChart(_Rebuildable, _core.MeshChart):
    __doc__ = _core.MeshChart.__doc__


class BilinearPatch(_Rebuildable, _core.BilinearPatch):
    __doc__ = _core.BilinearPatch.__doc__


class TrianglePatch(_Rebuildable, _core.TrianglePatch):
    __doc__ = _core.TrianglePatch.__doc__


class SplitPiece(_Rebuildable, _core.SplitPiece):
    __doc__ = _core.SplitPiece.__doc__


class Lambert(_Rebuildable, _core.Lambert):
    __doc__ = _core.Lambert.__doc__


class NormalizedPhong(_Rebuildable, _core.NormalizedPhong):
    __doc__ = _core.NormalizedPhong.__doc__


class AshikhminShirley(_Rebuildable, _core.AshikhminShirley):
    __doc__ = _core.AshikhminShirley.__doc__


class GgxReflection(_Rebuildable, _core.GgxReflection):
    __doc__ = _core.GgxReflection.__doc__


class DiffuseGgx(_Rebuildable, _core.DiffuseGgx):
    __doc__ = _core.DiffuseGgx.__doc__


class SmoothDielectric(_Rebuildable, _core.SmoothDielectric):
    __doc__ = _core.SmoothDielectric.__doc__


class RoughDielectric(_Rebuildable, _core.RoughDielectric):
    __doc__ = _core.RoughDielectric.__doc__


# Scene methods and properties that change the scene: each call is kept (tests/core/test_ray_solve.py
# checks that every other public member of the compiled Scene only reads it).
SCENE_CALLS = (
    "add_bilinear_patch",
    "add_triangle",
    "add_disk",
    "add_surface",
    "add_distant_light",
    "set_two_sided_emission",
    "set_spot_cone",
    "set_albedo_texture",
    "set_emission_texture",
    "set_specular_texture",
    "set_normal_texture",
    "set_spatial_coeffs",
    "set_integration_factor",
)
SCENE_PROPERTIES = ("world_radiance", "world_map")


def _kept_call(name: str):
    method = getattr(_core.Scene, name)

    def call(self: "Scene", *args: Any, **kwargs: Any) -> Any:
        result = method(self, *args, **kwargs)
        self._bsgi_calls.append((name, *_record(args, kwargs)))  # only calls that succeeded
        return result

    call.__name__ = name
    call.__doc__ = method.__doc__
    return call


def _kept_property(name: str) -> property:
    prop = getattr(_core.Scene, name)

    def set_value(self: "Scene", value: Any) -> None:
        prop.fset(self, value)
        self._bsgi_calls.append(("=" + name, (_kept(value),), {}))

    return property(prop.fget, set_value, doc=prop.__doc__)


class Scene(_core.Scene):
    __doc__ = _core.Scene.__doc__

    def __init__(self) -> None:
        super().__init__()
        self._bsgi_calls: list = []

    def __reduce__(self) -> tuple:
        return _rebuild, (type(self), (), {}, tuple(self._bsgi_calls))


for _name in SCENE_CALLS:
    setattr(Scene, _name, _kept_call(_name))
for _name in SCENE_PROPERTIES:
    setattr(Scene, _name, _kept_property(_name))
del _name


def settings_fields(settings: _core.SolverSettings) -> dict:
    """The solver settings as a dict (they pickle as such): every public field."""
    return {name: getattr(settings, name) for name in dir(settings)
            if not name.startswith("_") and not callable(getattr(settings, name))}


def settings_from(fields: dict) -> _core.SolverSettings:
    settings = _core.SolverSettings()
    for name, value in fields.items():
        setattr(settings, name, value)
    return settings
