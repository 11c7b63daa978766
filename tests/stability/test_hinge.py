"""The stability study's hinge (drawer_lib.stability.hinge): the closed form against a fine RK4
run, each integrator's order of convergence, and the divergences a stiff spring and a heavy
damper on a light link cause (as measured: Euler / implicit / implicitfast are
first order, RK4 fourth; a stiff joint breaks every integrator once w dt > 2; a heavy damper
breaks RK4 at every timestep while MuJoCo's Euler family integrates damping implicitly)."""

import math

import numpy as np
import pytest

from drawer_lib.stability.hinge import INTEGRATORS, Hinge, run_cell


@pytest.mark.parametrize("hinge", [Hinge(), Hinge(damping=10.0), Hinge(damping=2 * math.sqrt(10.0 * 0.35)),
                                   Hinge(stiffness=0.0)], ids=["under", "over", "critical", "free"])
def test_the_closed_form_is_what_rk4_converges_to(hinge):
    assert run_cell(hinge, "rk4", 2e-4).error < 1e-10
    t = np.linspace(0, 1, 5)
    assert hinge.exact(t)[0] == pytest.approx(hinge.q0)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_orders_of_convergence(integrator):
    h = Hinge()
    e1, e2 = run_cell(h, integrator, 2e-3).error, run_cell(h, integrator, 1e-3).error
    order = math.log2(e1 / e2)
    assert order == pytest.approx(4.0 if integrator == "rk4" else 1.0, abs=0.15)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_a_stiff_joint_on_a_light_link_diverges_once_w_dt_passes_2(integrator):
    stiff = Hinge(inertia=1e-3, stiffness=1e4, damping=0.0)  # w = 3162 rad/s
    bad = run_cell(stiff, integrator, 1e-3, 0.2)  # w dt = 3.2
    assert bad.diverged and math.isinf(bad.error) and bad.reason
    ok = run_cell(stiff, integrator, 1e-4, 0.2)  # w dt = 0.32: stable, its amplitude kept (the
    assert not ok.diverged and ok.error <= 2.05 * stiff.q0  # first-order phase error adds up over 100 periods)
    if integrator == "rk4":
        assert ok.error < 0.1 * stiff.q0  # 2.6 % of q0 after 100 periods (w dt = 0.32)


def test_a_heavy_damper_on_a_light_link_breaks_rk4_only():
    damped = Hinge(inertia=1e-3, stiffness=10.0, damping=1e3)  # b / I = 1e6 1/s
    for dt in (2e-3, 1e-4):
        assert run_cell(damped, "rk4", dt, 0.2).diverged
        for integrator in ("euler", "implicit", "implicitfast"):
            c = run_cell(damped, integrator, dt, 0.2)
            assert not c.diverged and c.error < 1e-3, (integrator, dt, c)


def test_bad_integrator_is_named():
    with pytest.raises(ValueError, match="'verlet'"):
        Hinge().model("verlet", 1e-3)
