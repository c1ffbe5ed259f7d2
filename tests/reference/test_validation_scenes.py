"""The validation scenes (issue 15; bench/validation) at the final preset against their committed
Mitsuba 3 references (3,000 random visible pairs each, reference noise 0.2-0.3%; never rendered
here): the relative RMSE and the worst object's mean radiance ratio are bounded within about 2x of
what was measured, so a regression fails; the issue's targets (final <= 1% on diffuse scenes,
<= 2% with GGX alpha >= 0.3, every surface's mean within 1%) are checked, as strict expected
failures stating the measured figures where they are not met (none since 6 December; open_box
until then). The final preset refines to 1% within five times its first solve's rays
(bsgi.refine); its first solve alone ("one solve", the refinement off) is what the error estimate
is judged on and what refinement gains against. Each scene is solved by
bench/study/solve_blend.py in a process of its own (about 6 minutes of CPU for the refined
finals, whose first passes are the one solves, 4 more for the estimate's other sets of checks);
the figures print with -s.

    .venv/bin/python -m pytest tests/reference/test_validation_scenes.py -s
"""
from __future__ import annotations

import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench" / "validation"))

# Measured at the final preset (bench/validation/validate.py measure --preset final; 6 December,
# its refinement within five times the first solve's rays): relative RMSE, worst object's mean
# ratio; the bounds sit within about 2x of them (the ratio's distance from 1). (Within three times,
# 5 December: open_box 2.10%, one refinement pass, its floor and left wall 2.7% and 4.1%, now
# 1.6% and 2.4%; table_spheres 1.52%; the others as now.)
# table_spheres against its reference remade with Blender's smooth shading normals (6 December;
# the flat-shaded spheres of the reference before measured 1.50%, the GGX sphere 0.9952), and on
# 7 December with Cycles' height-correlated shadowing on its GGX sphere in the solve and the
# reference (0.61%, 1.0003 the day before; open_box the same to 0.01 points).
MEASURED = {"open_box": (0.0139, 0.9963),  # the block
            # the GGX sphere; 7 December with the gather's Fibonacci lattice, whose estimate asks the
            # sphere for spatial knots and integration nodes the cost budget refuses together: its
            # spatial knots alone (refine.py with_lesser_refinements; 0.87% and 1.0025 with the
            # table refined alone, 0.96% when the pass stopped at the sphere)
            "table_spheres": (0.0074, 1.0010),
            "ceiling_light": (0.0042, 1.0006),  # the floor (nothing over the target: one solve)
            "thin_occluder": (0.0050, 0.9952),  # the small wall
            "leaning_board": (0.0071, 0.9987)}  # the narrow wall
# One solve (the refinement off; --overrides '{"refine_to_error": 0}'), the final preset until it
# refined. (3 December, with the sharpened fit and the hemisphere rule's Gauss nodes; before: 3.76%,
# 4.13%, 0.81%, 2.25%; thin_occluder then 1.88% until the final preset's discontinuity knots,
# open_box 3.56% and table_spheres 2.76% until the glossy splines' angular axes were sharpened;
# with two final passes instead of four 3.51%, 1.85%, 0.42%, 1.21%, 2.78%; without the coarse
# correction, 5 December, 3.40%, 1.72%, 0.42%, 1.18%, 2.61%, leaning_board's board 1.0064.)
MEASURED_ONE_SOLVE = {"open_box": (0.0337, 0.9957),  # the ceiling
                      "table_spheres": (0.0096, 1.0022),  # the GGX sphere (1.00%, 1.0021 before the
                      # gather's lattice; 1.71%, 0.9969 flat-shaded)
                      "ceiling_light": (0.0042, 1.0006),  # the floor
                      "thin_occluder": (0.0118, 0.9975),  # the small wall
                      # (added 3 December: the board's back bright, the wedge behind it lit through
                      # the coarse bounces' blurred shadow edges at its open ends, until the coarse
                      # correction; README, validation section; 2.66% until the nodes beside a
                      # narrow penumbra's jump left it)
                      "leaning_board": (0.0259, 1.0016)}  # the board
# The issue's targets: 1% on diffuse scenes, 2% where a GGX surface of alpha >= 0.3 is seen.
TARGET = {"open_box": 0.02, "table_spheres": 0.02, "ceiling_light": 0.01, "thin_occluder": 0.01, "leaning_board": 0.01}


def meets_target(scene):
    error, ratio = MEASURED[scene]
    return error <= TARGET[scene] and abs(ratio - 1) <= 0.01


_solved = {}
ONE_SOLVE = {"refine_to_error": 0}


def final(scene, overrides=None, label="final"):
    """The scene at the final preset with `overrides` (solved once a session, printed). The
    refined final's first pass is kept as one_solve(scene)'s (the same solve: the core does not
    read refine_to_error), which saves a solve a scene."""
    import validate

    key = (scene, repr(overrides))
    if key not in _solved:
        _solved[key] = validate.measure(scene, "final", overrides, first_pass=overrides is None)
        validate.print_row(scene, label, _solved[key])
        if "first_pass" in _solved[key]:  # a refined final (the preset's refine_to_error > 0)
            first = _solved[(scene, repr(ONE_SOLVE))] = _solved[key]["first_pass"]
            validate.print_row(scene, "final, one solve (its first pass)", first)
    return _solved[key]


def one_solve(scene, overrides=None, label="final, one solve"):
    if overrides is None:
        final(scene)  # its first pass
    return final(scene, {**ONE_SOLVE, **(overrides or {})}, label)


@pytest.mark.slow
@pytest.mark.blender
@pytest.mark.parametrize("scene", sorted(TARGET))
@pytest.mark.parametrize("refined", [True, False], ids=["final", "one solve"])
def test_final_preset_within_measured_bounds(scene, refined):
    r = final(scene) if refined else one_solve(scene)
    error, ratio = (MEASURED if refined else MEASURED_ONE_SOLVE)[scene]
    assert r["pairs"] >= 2900  # of 3,000: few lost to tessellation differences
    assert r["rel_rmse"] < 2 * error, r["rel_rmse"]
    assert abs(r["worst_surface_ratio"] - 1) < 2 * abs(ratio - 1), r["surfaces"]


@pytest.mark.slow
@pytest.mark.blender
@pytest.mark.parametrize("scene", sorted(TARGET))
def test_issue_target(scene, request):
    error, ratio = MEASURED[scene]
    if not meets_target(scene):
        request.applymarker(pytest.mark.xfail(strict=True, reason=(
            f"issue 15 target: final <= {100 * TARGET[scene]:.0f}% and every surface's mean within 1%; measured "
            f"{100 * error:.1f}%, worst surface ratio {ratio:.3f} (causes in the README's validation section)")))
    r = final(scene)
    assert r["rel_rmse"] <= TARGET[scene]
    assert abs(r["worst_surface_ratio"] - 1) <= 0.01


# The error estimate per object at final's one solve (what refinement acts on), against Mitsuba
# (its noise taken out): within a factor of
# two (the issue's test) on every object with at least 100 pairs and an error over twice its
# reference's noise, as the geometric mean over four sets of checks (SolverSettings.error_checks_seed:
# an object's error sits in thin bands beside contact lines and shadow edges that one set of checks
# hits or misses by chance), but these known misses (measured geometric means):
# (open_box's block was one, at 2.2, while the input term took one order of convergence per
# surface; with the order local to where the gather's rays land, InputScales, 1.73.)
# table_spheres' spheres, over since their reference was remade with smooth shading normals (6
# December): their measured errors fell (0.63% and 0.93%, from 1.1-1.5% against flat facets),
# their estimates did not (1.2-1.8% and 1.7-2.4%, the input and fit terms the most).
KNOWN_ESTIMATE_MISSES = {("leaning_board", "Box"): 5.2,  # the input term (the floor's contact lines)
                         ("table_spheres", "Diffuse sphere"): 2.33, ("table_spheres", "GGX sphere"): 2.12}
# (At one set of 48 checks with the integration error added to the spline's misfit of the phase's
# gather, six objects missed: open_box's floor 0.36, table_spheres' diffuse sphere 2.79 and table
# 2.34, leaning_board's box 8.5 and floor 3.2; over four sets their means were 0.73, 2.48, 1.82,
# 4.0 and 1.1, each set's ratios a factor of 1.2 to 1.9 (the standard deviation of log2) apart.)
SEEDS = range(4)
_estimates = {}


def estimates(scene):
    """Per seed, one final solve's per-object figures (seed 0: one_solve(scene)'s)."""
    if scene not in _estimates:
        _estimates[scene] = [one_solve(scene, {"error_checks_seed": seed} if seed else None)["surfaces"] for seed in SEEDS]
    return _estimates[scene]


@pytest.mark.slow
@pytest.mark.blender
@pytest.mark.parametrize("scene", sorted(TARGET))
def test_error_estimate_within_a_factor_of_two_per_object(scene):
    import numpy as np

    per_seed = estimates(scene)
    judged = {}
    for name, s in per_seed[0].items():
        if s["pairs"] >= 100 and s["measured"] > 2 * s["noise"]:
            judged[name] = np.array([surfaces[name]["estimated"] for surfaces in per_seed]) / s["measured"]
    print({name: [round(x, 2) for x in ratio] for name, ratio in judged.items()})
    assert judged or scene == "ceiling_light"  # its errors are at its reference's noise
    # (open_box's left wall, where the panel pierces it, was 0.29 before the checks under the
    # panel's lit back counted: 0.55; 0.67 with four final passes)
    for name, ratio in judged.items():
        gmean = float(np.exp(np.log(ratio).mean()))
        if (scene, name) in KNOWN_ESTIMATE_MISSES:
            # Still known: within 1.5x of the figure above either way, so a change shows.
            known = KNOWN_ESTIMATE_MISSES[(scene, name)]
            assert known / 1.5 <= gmean <= known * 1.5, (name, ratio)
            continue
        assert 0.5 <= gmean <= 2, (name, ratio)
        assert np.all((ratio >= 0.25) & (ratio <= 4)), (name, ratio)  # no set of checks far off


# The estimate the user sees after final's refinement (its last solve's; one set of checks, seed 0),
# judged as above. Known misses, all over (measured with the refinement within three times the
# first solve's rays, at seeds 0-3; within five times, 6 December, seed 0, in brackets): open_box's
# GGX panel 2.80 (3.29; 2.8-3.3: its error where the pairs see it fell 2.7% -> 1.1% with 1.5x its
# spatial coefficients, its estimate's fit part 3.1% -> 2.8% only: that is its part outside the
# box, which no pair sees; over its whole surface the estimate is 0.93 of its error, next test),
# its block 2.50 (2.71; 1.9-3.6; the input term), and leaning_board's floor 2.59 (2.49; 1.3-4.8;
# seed 0's checks are its high set in one solve too: 2.41 against 0.89-1.43) and box 7.5 (not
# judged: its error within twice the noise; 4.0-17; the input term, as in one solve). And since
# 7 December (Cycles' shadowing on the GGX sphere, solve and reference) table_spheres' spheres,
# as in one solve (below): their measured errors 0.65% and 0.54% at 2.2-2.4x the reference's
# noise, their estimates 1.66% and 1.24% (the input term the most): 2.55 and 2.30.
KNOWN_REFINED_ESTIMATE_MISSES = {("open_box", "Panel"): 3.29, ("open_box", "Block"): 2.71,
                                 ("leaning_board", "Floor"): 2.49, ("leaning_board", "Box"): 7.5,
                                 ("table_spheres", "Diffuse sphere"): 2.55, ("table_spheres", "GGX sphere"): 2.30}


@pytest.mark.slow
@pytest.mark.blender
@pytest.mark.parametrize("scene", sorted(TARGET))
def test_refined_error_estimate_within_a_factor_of_two_per_object(scene):
    judged = {name: s["estimated"] / s["measured"] for name, s in final(scene)["surfaces"].items()
              if s["pairs"] >= 100 and s["measured"] > 2 * s["noise"]}
    print({name: round(ratio, 2) for name, ratio in judged.items()})
    assert judged or scene == "ceiling_light"
    for name, ratio in judged.items():
        known = KNOWN_REFINED_ESTIMATE_MISSES.get((scene, name))
        if known:
            assert known / 1.5 <= ratio <= known * 1.5, (name, ratio)
        else:
            assert 0.5 <= ratio <= 2, (name, ratio)


# open_box's GGX panel passes 14 cm through the left wall: 5.2% of it lies outside the box, where
# no light reaches (its exact radiance 0: the world is black, the walls' backs unlit) and no pair
# looks (their eyes must be in open space). The error estimate's checks count it (a viewer outside
# the box would see it). bench/validation/unlit_part.py: the spline there is 16% of the panel's
# mean inside as an RMS, 3.75% of the panel's relative RMS error, in one solve; 14% and 3.10% after
# final's refinement. With the error measured inside (2.71%, 1.09%), the panel's error over its
# whole surface is 4.6% and 3.3%, estimated 3.3% and 3.0% (0.72 and 0.93 of it); the refinement
# lowered the inside's error and not the bleed over the oblique line where the panel meets the
# wall, which knots along parameter lines cannot follow (the paper's 5.1 split would).
@pytest.mark.slow
@pytest.mark.blender
def test_the_panels_estimate_counts_its_unlit_part_outside_the_box():
    import json
    import math
    import subprocess

    import validate

    run = subprocess.run([sys.executable, str(ROOT / "bench" / "validation" / "unlit_part.py"), "open_box", "Panel",
                          "--outside", "-1", "1", "-1", "1", "0", "2", "--overrides", json.dumps(ONE_SOLVE)],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    (panel,) = json.loads(run.stdout.strip().splitlines()[-1]).values()
    print(panel)
    assert 0.04 < panel["outside_fraction"] < 0.06  # the geometry: 5.2%
    share = panel["outside_share"]
    assert 0.019 < share < 0.075, share  # measured 0.0375
    measured = one_solve("open_box")["surfaces"]["Panel"]
    whole = math.sqrt(measured["measured"] ** 2 * (1 - panel["outside_fraction"]) + share ** 2)
    assert abs(panel["estimated_error"] / measured["estimated"] - 1) < 1e-6  # the same solve
    assert 0.5 <= panel["estimated_error"] / whole <= 2, (panel["estimated_error"], whole)  # measured 0.72


# The reference preset (final's bounces; a final gather with discontinuity knots, 4x the spatial
# coefficients per direction, 2x the integration nodes) on the three diffuse scenes, where it meets
# the issue's target (validate.py measure --preset reference): relative RMSE, worst object's ratio.
# ceiling_light's error is at its reference's noise (0.32%): bounded at twice that. leaning_board
# met it once the nodes beside its board's foot stayed inside the wedge (1.8% -> 0.83%; the
# floor's nodes there had gathered the lit room's light from above the board), 0.76% with the
# coarse correction. The GGX scenes
# (open_box 1.53%, table_spheres 0.55% (1.47% against its flat-shaded reference), 2-3.5 minutes of CPU each) are measured by the same command
# and not solved here.
MEASURED_REFERENCE = {"thin_occluder": (0.0036, 0.9995),  # the large wall
                      "ceiling_light": (0.0034, 0.9996),  # the ceiling
                      "leaning_board": (0.0076, 1.0011)}  # the board


@pytest.mark.slow
@pytest.mark.blender
@pytest.mark.parametrize("scene", sorted(MEASURED_REFERENCE))
def test_reference_preset_meets_the_target(scene):
    import validate

    r = validate.measure(scene, "reference")
    validate.print_row(scene, "reference", r)
    error, ratio = MEASURED_REFERENCE[scene]
    bound = max(2 * error, 2 * r["reference_noise"])
    assert r["rel_rmse"] <= min(TARGET[scene], bound), r["rel_rmse"]
    assert abs(r["worst_surface_ratio"] - 1) <= min(0.01, 2 * abs(ratio - 1)), r["surfaces"]
    # Better than final's one solve (leaning_board's 0.76% is not better than final's refinement,
    # 0.70%, at 3x final's CPU time)
    base = one_solve(scene)
    assert r["rel_rmse"] < base["rel_rmse"]


# Final's refinement to 1% on thin_occluder (validate.py measure --scene thin_occluder --preset
# final; its one solve with --overrides '{"refine_to_error": 0}'): the large wall's estimate is its final
# gather's integration (2.1% of 2.1%; the floor's light seen at grazing angles), whose nodes per
# axis refinement doubles there; the floor (its shadow's oblique edges) gets 1.5 times its
# coefficients. Measured (four final passes), after one pass: the large wall 1.74% -> 0.71%, the
# scene 1.18% -> 0.50% (every surface's estimate under 1%) at 1.4 s CPU against 0.6 s: a setting
# that meets the issue's 1% target there. (While the estimate counted the integration error twice,
# two passes and four times the nodes: 0.47% at 14.8 s CPU against 1.2 s.)
@pytest.mark.slow
@pytest.mark.blender
def test_refinement_raises_the_integration_where_the_estimate_says_the_gather_errs():
    r, base = final("thin_occluder"), one_solve("thin_occluder")
    refined = {s["name"]: s for s in r["refinement"]["surfaces"]}
    wall = next(s for name, s in refined.items() if name.startswith("Large wall"))
    assert wall["integration_factor"] >= 2, wall
    before, after = base["surfaces"]["Large wall"]["rel_rmse"], r["surfaces"]["Large wall"]["rel_rmse"]
    assert after <= 0.5 * before and after <= 0.010, (before, after)
    assert r["rel_rmse"] <= min(TARGET["thin_occluder"], 2 * 0.0048), r["rel_rmse"]


# The same refinement on the two scenes one final solve leaves furthest from the issue's targets
# (relative RMSE, worst object's mean ratio, measured): open_box 3.37% -> 2.10% within the budget of
# 3 (1.38% refined without a budget, at 6x the CPU time: its GGX panel's 4D refinement is dear),
# leaning_board 2.59% -> 0.70% (its 1% met; 1.51% until the contact lines' bands: the refined
# floor's 72 final coefficients a direction put its node beside the board's foot above the board).
# (table_spheres 1.71% -> 1.52%; ceiling_light's surfaces all meet the target in one solve.)
REFINED = {"open_box": (0.0210, 1.0036), "leaning_board": (0.0070, 0.9982)}  # the panel, the narrow wall


@pytest.mark.slow
@pytest.mark.blender
@pytest.mark.parametrize("scene", sorted(REFINED))
def test_refinement_to_one_percent_where_final_is_furthest(scene):
    r, base = final(scene), one_solve(scene)
    error, ratio = REFINED[scene]
    assert r["rel_rmse"] <= 1.5 * error and r["rel_rmse"] < 0.7 * base["rel_rmse"], (r["rel_rmse"], base["rel_rmse"])
    assert r["refinement"]["passes"] >= 1
    assert abs(r["worst_surface_ratio"] - 1) <= min(0.01, 2 * abs(ratio - 1)), r["surfaces"]


# The coarse bounces light leaning_board's wedge behind the board through the board's blurred
# ends. The regathers carry the finals' light a bounce further each into it (the board's mean,
# both sides, 1.0140 with two passes, 1.0110 with three, 1.0064 with the final preset's four); the
# coarse correction (final_correction_bounces, 8 at final) carries the coarse light's error over
# all the bounces at once before the second: 1.0016 (validate.py measure --scene leaning_board
# --preset final --overrides '{"refine_to_error": 0[, "final_correction_bounces": 0]}'); inside the
# wedge the floor and wall 1.12x Mitsuba's without it, 1.00x with it (in one solve, as measured).
@pytest.mark.slow
@pytest.mark.blender
def test_the_coarse_correction_carries_the_fine_light_into_a_wedge():
    regathers = one_solve("leaning_board", {"final_correction_bounces": 0}, "final, one solve, regathers alone")
    r = one_solve("leaning_board")
    before, after = regathers["surfaces"]["Board"]["ratio"] - 1, r["surfaces"]["Board"]["ratio"] - 1
    assert 0 <= after <= 0.5 * before, (before, after)  # measured 0.0016 against 0.0064
    assert r["rel_rmse"] <= regathers["rel_rmse"]


@pytest.mark.slow
@pytest.mark.blender
def test_cycles_bake_sees_the_back_of_two_sided_planes():
    """validate.py cycles (the study's bake; bench/validation/cycles.csv) on thin_occluder at 16
    samples: the occluder and the small wall, seen from both sides, read their back sides' bake.
    Measured: occluder 1.72%, small wall 5.9%, scene 4.2%; with the front's bake for every pair
    95% and 67%."""
    import validate

    (row,) = validate.cycles("thin_occluder", [16], 256)
    surfaces = row["surfaces"]
    print({name: round(s["rel_rmse"], 4) for name, s in surfaces.items()}, row["rel_rmse"], row["cpu_seconds"])
    assert row["pairs"] == 3000
    assert surfaces["Occluder"]["rel_rmse"] < 0.035
    assert surfaces["Small wall"]["rel_rmse"] < 0.12
    assert row["rel_rmse"] < 0.085
