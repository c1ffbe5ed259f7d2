"""One solve of a .blend in a process of its own (so its peak memory is its own), then the
solution's radiance at the study's pairs. Prints a JSON line of figures.

    python bench/study/solve_blend.py scene.blend settings.json pairs.npz out.npz

settings.json: {"preset": "preview", "overrides": {"spatial_coeffs": 8, ...}}; with "first_pass": true
a refined solve (refine_to_error > 0) also writes its first pass's radiance and estimate, which
are those of one solve without the refinement, to out.first.npz (and its figures under
"first_pass"): one process gives both. The scene comes from
the add-on's export, as a user's solve gets it; the pairs' eye rays are cast against the solver's
surfaces to find what each eye sees (surface, u, v)."""
from __future__ import annotations

import json
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import blend_scene  # noqa: E402


def status_mb(key):
    # VmHWM, the peak, belongs to this process image (ru_maxrss would carry the parent's over exec).
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) / 1024


def settings_of(spec: dict):
    import bsgi

    settings = bsgi.SolverSettings.preset(spec["preset"])
    for name, value in spec.get("overrides", {}).items():
        if not hasattr(settings, name):
            raise ValueError(f"no solver setting '{name}'")
        setattr(settings, name, value)
    return settings


def knob_overrides_objects(context, overrides: dict):
    """A swept knob wins over an object's own setting of it (this session's copy, never saved):
    otherwise glass_sheet's sheet, set to 12 angular coefficients, would ignore the sweep."""
    for obj in context.scene.objects:
        own = getattr(obj, "bsgi", None)
        if own is None:
            continue
        if "spatial_coeffs" in overrides:
            own.spatial_coeffs = 0
        if "angular_coeffs_min" in overrides or "angular_coeffs_max" in overrides:
            own.angular_coeffs = 0


def surfaces_of(export):
    """The exported objects' surfaces as the solved scene holds them, with their scene indices."""
    index = [first + k for exported in export.objects for _, first, count in exported.patches for k in range(count)]
    return [export.scene.surface(i) for i in index], np.array(index)


def radiance_at_pairs(export, solution, pairs, tolerance):
    """The solution's radiance seen from each pair's eye towards its point; NaN where the solver's
    geometry is not hit within tolerance of the point (tessellation differences at silhouettes).
    Also the scene index of the surface each pair sees (-1 where NaN)."""
    import bsgi

    surfaces, index = surfaces_of(export)
    caster = bsgi.RayCaster(surfaces)
    eye, point = pairs["eye"], pairs["point"]
    d = point - eye
    dist = np.linalg.norm(d, axis=1)
    d /= dist[:, None]
    hit = caster.closest_hit(eye, d)
    ok = (hit["surface"] >= 0) & (np.abs(hit["t"] - dist) < tolerance)
    out = np.full((len(eye), 3), np.nan)
    seen = np.full(len(eye), -1)
    for s in np.unique(hit["surface"][ok]):
        rows = np.nonzero(ok & (hit["surface"] == s))[0]
        # Towards the eye, in the surface's radiance frame (the shading frame on smooth faces).
        out[rows] = solution.surfaces[int(index[s])].evaluate(hit["uv"][rows], hit["leaving"][rows])
        seen[rows] = index[s]
    return out, seen


def refuse_light_the_reference_lacks(context, export):
    """The Mitsuba reference (blend_scene.py, mitsuba_scene.py) has emissive surfaces and area
    lights only: a scene the solver also lights by point, spot or sun lights or the world would be
    compared with a darker reference."""
    extra = [f"{o.data.type.lower()} light '{o.name}'" for o in context.scene.objects
             if o.type == "LIGHT" and o.data.type in {"POINT", "SPOT", "SUN"}]
    if max(export.scene.world_radiance) > 0 or export.scene.world_map is not None:
        extra.append(f"world '{context.scene.world.name}'")
    if extra:
        raise SystemExit(f"the study's Mitsuba reference has no {', '.join(extra)}: set them to black or remove "
                         "them to study this scene")


ERROR_PARTS = ("fit", "input", "integration", "tail")  # the estimate's parts, the columns of error_parts


def open_and_export(blend, spec: dict):
    """The .blend opened with the add-on loaded, a swept knob set over the objects' own, and
    exported as a user's solve gets it: (export, solver settings of `spec`)."""
    import bpy

    blend_scene.load_addon()
    from bsgi_addon import properties
    from bsgi_addon.export import export_scene

    bpy.ops.wm.open_mainfile(filepath=str(pathlib.Path(blend).resolve()))
    settings = settings_of(spec)
    # The quality also says which Principled coats are solved (materials.coat_threshold).
    if spec["preset"].upper() in {p[0] for p in properties.PRESETS}:
        bpy.context.scene.bsgi.preset = spec["preset"].upper()
    knob_overrides_objects(bpy.context, spec.get("overrides", {}))
    return export_scene(bpy.context.evaluated_depsgraph_get()), settings


def main():
    blend, settings_json, pairs_npz, out_npz = blend_scene.main_argv()
    import bpy

    import bsgi

    spec = json.loads(pathlib.Path(settings_json).read_text())
    export, settings = open_and_export(blend, spec)
    refuse_light_the_reference_lacks(bpy.context, export)
    pairs = dict(np.load(pairs_npz))
    # Reset the peak to the current size (Linux clear_refs), so loading Blender does not count.
    pathlib.Path("/proc/self/clear_refs").write_text("5")
    before = status_mb("VmRSS")
    start, cpu = time.perf_counter(), time.process_time()
    scale = float(np.ptp(pairs["point"], axis=0).max())
    first = {}

    if spec.get("first_pass") and settings.refine_to_error > 0:
        from bsgi.refine import refined_solve
        from bsgi.split import split_scene

        # As bsgi.solve does: split where surfaces cross, answer for the exported scene.
        split = split_scene(export.scene) if settings.split_crossings else None
        answer = split.solution if split else (lambda s: s)

        def solve_once(sides):
            solution = bsgi._core.solve(split.scene if split else export.scene, settings, bsgi.Progress(), sides)
            if not first:  # read now: the refinement changes the scene's coefficients after it
                first.update(seconds=time.perf_counter() - start, cpu_seconds=time.process_time() - cpu,
                             bounces=solution.stats["bounces"], coefficients=solution.stats["coefficients"],
                             rays=solution.stats["rays"] + solution.stats["estimate_rays"])
                write_solution(out_npz.replace(".npz", ".first.npz"), export, answer(solution), pairs, scale)
            return solution

        solution = answer(refined_solve(split.scene if split else export.scene, settings, solve_once))
    else:
        solution = bsgi.solve(export.scene, settings)
    seconds, cpu_seconds = time.perf_counter() - start, time.process_time() - cpu
    peak = status_mb("VmHWM")
    write_solution(out_npz, export, solution, pairs, scale)
    print(json.dumps({"seconds": seconds, "cpu_seconds": cpu_seconds, "peak_mb": peak - before, "coefficients": solution.stats["coefficients"],
                      "bounces": solution.stats["bounces"],
                      # of all passes, with refine_to_error (bsgi.refine)
                      "rays": getattr(solution, "refinement", solution.stats)["rays"],
                      "refinement": getattr(solution, "refinement", None),
                      **({"first_pass": first} if first else {})}))


def write_solution(path, export, solution, pairs, scale):
    """The solution's radiance at the pairs, the surfaces they see and its error estimate."""
    ours, seen = radiance_at_pairs(export, solution, pairs, 1e-3 * scale)
    estimates = np.array([r["estimated_error"] for r in solution.reports if r["shape"]])
    parts = np.array([[r["error_parts"][k] for k in ERROR_PARTS] for r in solution.reports if r["shape"]]).reshape(-1, 4)
    np.savez(path, radiance=ours, surface=seen, estimated_error=estimates, error_parts=parts,
             receivers=np.array([i for i, r in enumerate(solution.radiance) if r is not None]),
             names=np.array([r["name"] for r in solution.reports if r["shape"]]))


if __name__ == "__main__":
    main()
