"""The second final gather (SolverSettings.final_passes = 2, in the preview and final presets)
takes the indirect light from the first final gather's splines instead of the coarse ones: a box
face turned away from the lamp gets most of its light from a narrow strip of floor in front of it,
which the coarse floor spline blurs with the box's shadow beside it. Against Mitsuba 3 (the
Cornell box of test_error_estimate, its reference shared), per surface, one pass and two."""
import numpy as np
import pytest

import bsgi
from reference import scene_spec
from test_error_estimate import reference


def per_surface(spec, pairs, ours, ref):
    """Per lit surface name: (mean ratio ours / Mitsuba, relative RMS error)."""
    out = {}
    for i in np.unique(pairs["patch"]):
        m = pairs["patch"] == i
        mean = ref[m].mean()
        if mean > 0:
            out[spec.patches[i].name] = (ours[m].mean() / mean, np.sqrt(((ours[m] - ref[m]) ** 2).mean()) / mean)
    return out


def preview_against_mitsuba(**changes):
    """The Cornell box solved at the preview preset with some settings changed: (per_surface,
    relative RMS error over all pairs, the solution's stats)."""
    spec, pairs, ref, _ = reference("cornell")
    scene = scene_spec.to_bsgi(spec)
    settings = bsgi.SolverSettings.preset("preview")
    for name, value in changes.items():
        setattr(settings, name, value)
    solution = bsgi.solve(scene, settings)
    ours = scene_spec.solved_radiance(scene, solution, pairs)
    return per_surface(spec, pairs, ours, ref), np.sqrt(((ours - ref) ** 2).mean()) / ref.mean(), solution.stats


@pytest.mark.slow
def test_second_final_gather_lights_the_face_beside_a_narrow_shadow():
    figures = {}
    for passes in (1, 2):
        figures[passes], _, stats = preview_against_mitsuba(final_passes=passes)
        figures[passes, "seconds"] = stats["seconds_final"]
    print(f"\nfinal gather {figures[1, 'seconds']:.2f} s, with a regather {figures[2, 'seconds']:.2f} s")
    for name in figures[1]:
        (r1, e1), (r2, e2) = figures[1][name], figures[2][name]
        print(f"  {name:12s} mean ratio {r1:.4f} -> {r2:.4f}, rel RMSE {e1:.4f} -> {e2:.4f}")
    # The short box's face away from the lamp (measured 1.138 -> 1.035, RMSE 20.7% -> 9.4%; 1.179 ->
    # 1.065 and 25.0% -> 16.8% before the preview's adaptive knots). The tall box's face over the
    # floor's contact line took 5.4% -> 2.5% from the regather before them; they bring it to 2.5%
    # in the first pass (2.48% -> 2.49%).
    assert figures[2]["short box 2"][0] < 1.10 < figures[1]["short box 2"][0]
    assert figures[2]["short box 2"][1] <= 0.6 * figures[1]["short box 2"][1]
    # No surface loses (all gained: the walls 2-16%, the other box faces up to 66%).
    for name in figures[1]:
        assert figures[2][name][1] <= 1.05 * figures[1][name][1], name
