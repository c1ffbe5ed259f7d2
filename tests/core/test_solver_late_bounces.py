"""Late bounces (SolverSettings.late_bounces_after): after the first bounces, each gathers with a
quarter of the hemisphere's rays. A late increment is smooth and a small share of the light, so
the solve's error against Mitsuba 3 must not grow while its rays fall (the Cornell box of
test_error_estimate at the preview preset, its reference shared)."""
import pytest

from test_solver_final_passes import preview_against_mitsuba


@pytest.mark.slow
def test_late_bounces_cost_rays_not_accuracy():
    (full, e0, stats0), (late, e1, stats1) = (preview_against_mitsuba(late_bounces_after=k) for k in (0, 1))
    rays0, b0, rays1, b1 = stats0["rays"], stats0["bounces"], stats1["rays"], stats1["bounces"]
    print(f"\nall bounces full: {e0:.4f} error, {rays0} rays, {b0} bounces; late after 1: {e1:.4f}, {rays1} rays, "
          f"{b1} bounces ({rays1 / rays0:.3f} of the rays)")
    for name in full:
        print(f"  {name:12s} rel RMSE {full[name][1]:.4f} -> {late[name][1]:.4f}, mean ratio {full[name][0]:.4f} -> {late[name][0]:.4f}")
    assert rays1 <= 0.8 * rays0  # measured 0.661
    assert e1 <= 1.02 * e0  # measured 0.0293 both
    for name in full:
        assert late[name][1] <= 1.1 * full[name][1] + 0.002, name
        assert abs(late[name][0] - full[name][0]) <= 0.005, name
