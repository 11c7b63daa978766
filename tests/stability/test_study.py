"""The stability study's matrix (drawer_lib.stability.study, drawer_lib.stability.pipeline): the
extreme cases find what was measured, the choice rule, the remedies, and the
stage's outputs on the tiny analytic kitchen."""

import dataclasses
import json
import math

import pytest
import sim_fixtures as F

from drawer_lib.errors import ConfigError, InputError
from drawer_lib.io.parts import write_parts
from drawer_lib.runner import StageRun
from drawer_lib.sim.mjcf import build_spec, compile_spec, write_mjcf
from drawer_lib.stability.hinge import Hinge
from drawer_lib.stability.pipeline import StabilityConfig, read_choice, read_matrix, run_stability
from drawer_lib.stability.study import (REMEDY_ARMATURE, REMEDY_DAMPING, Cell, choose, extreme_cases, hinge_case,
                                  reference_trace, remedy, run_cell, simulate_case, twin_case)


@pytest.fixture(scope="module")
def cases():
    return {c.name: c for c in extreme_cases()}


def test_stiff_joint_diverges_on_every_integrator_once_w_dt_passes_2(cases):
    c = cases["stiff_joint"]  # w = 3162 rad/s
    for integ in ("euler", "implicit", "implicitfast", "rk4"):
        assert run_cell(c, integ, 1e-3, None).diverged  # w dt = 3.2
        assert not run_cell(c, integ, 1e-4, None).diverged  # w dt = 0.32


def test_heavy_damping_and_tiny_armature_break_rk4_only(cases):
    for name in ("heavy_damping", "tiny_armature"):
        for dt in (1e-4, 2e-3):
            assert run_cell(cases[name], "rk4", dt, None).diverged, (name, dt)
            for integ in ("euler", "implicit", "implicitfast"):  # MuJoCo integrates joint damping implicitly
                c = run_cell(cases[name], integ, dt, None)
                assert not c.diverged and c.error < 1e-3, (name, integ, dt, c)


def test_stiff_servo_needs_an_implicit_integrator_at_a_millisecond(cases):
    c = cases["stiff_servo"]  # the servo's kv is explicit in Euler, implicit in implicit(fast)
    assert run_cell(c, "euler", 1e-3, None).diverged
    for integ in ("implicit", "implicitfast"):
        cell = run_cell(c, integ, 1e-3, None)
        assert not cell.diverged and cell.error < 0.1
    assert run_cell(c, "rk4", 1e-4, None).error < 1e-5  # the closed form is right


def test_odd_axes_are_the_unit_axis(cases):
    unit = hinge_case("unit", Hinge(inertia=0.35, stiffness=10.0, damping=1.0), 1.0)
    for name in ("axis_near_x", "axis_non_unit"):
        for integ, dt in (("implicitfast", 2e-3), ("rk4", 1e-3)):
            a, b = run_cell(cases[name], integ, dt, None), run_cell(unit, integ, dt, None)
            assert not a.diverged and a.error == pytest.approx(b.error, rel=1e-6, abs=1e-12)
    assert run_cell(cases["axis_non_unit"], "rk4", 1e-3, None).error < 1e-9


def test_zero_range_is_refused_by_mujoco_and_its_narrowest_limit_holds(cases):
    c = cases["zero_range"]
    assert "refuses range [0, 0]" in c.note
    for integ in ("euler", "implicitfast", "rk4"):
        cell = run_cell(c, integ, 2e-3, None)
        assert not cell.diverged and cell.error < 2e-4, cell  # the soft limit lets the 150 N drive in < 0.2 mm


def test_contact_rich_keeps_the_blocks_in_the_drawer(cases):
    c = dataclasses.replace(cases["contact_rich"], duration=0.3)
    ref = reference_trace(c)
    assert ref.reason is None and ref.obs[-1, 0] - ref.obs[0, 0] > 0.05  # the blocks ride along
    for integ in ("euler", "implicitfast"):
        cell = run_cell(c, integ, 2e-3, ref)
        assert not cell.diverged and cell.error < 0.01, cell
    # the check that catches a block falling out: it sits below the drawer's bottom
    fell = dataclasses.replace(c, setup=lambda m, d: (c.setup(m, d), d.qpos.__setitem__(slice(9, 10), -0.5)))
    assert "fell through" in str(simulate_case(fell, "implicitfast", 2e-3).reason)


def test_remedies_make_the_stiff_joint_stable(cases):
    c = cases["stiff_joint"]
    r = remedy(c, "implicitfast", 2e-3)
    # each remedy is the smallest value of its grid that makes the case stable: it is stable, and
    # every smaller value of the grid still diverges
    for key, grid in (("armature", REMEDY_ARMATURE), ("damping", REMEDY_DAMPING)):
        assert r[key] in grid, r
        assert simulate_case(c, "implicitfast", 2e-3, **{key: r[key]}).reason is None, (key, r)
        assert all(simulate_case(c, "implicitfast", 2e-3, **{key: v}).reason for v in grid if v < r[key]), (key, r)
    # armature: the period grows with sqrt(I + a) until w dt < 2 (a > k dt^2 / 4 = 0.01 kg·m^2);
    # damping, integrated implicitly, damps the fast mode
    assert r["armature"] >= 0.01 and r["damping"] > 0
    # RK4 integrates damping explicitly: no damping in the grid helps it
    assert remedy(cases["stiff_joint"], "rk4", 2e-3)["damping"] is None


def _cell(integ, dt, err, case="twin", diverged=False):
    return Cell(case, "nominal", integ, dt, math.inf if diverged else err, "m", "rk4", 0.1, diverged, None)


def test_choose_takes_the_largest_passing_timestep_and_ties_without_the_clock():
    cells = [_cell("euler", 1e-3, 5e-4), _cell("implicitfast", 1e-3, 5e-4), _cell("rk4", 1e-3, 1e-4),
             _cell("implicitfast", 2e-3, 9e-4), _cell("euler", 2e-3, 2e-3), _cell("rk4", 5e-3, 0, diverged=True),
             _cell("implicitfast", 2e-3, 1e-5, case="other")]
    ch = choose(cells, 1e-3)
    assert (ch.integrator, ch.timestep, ch.nominal_error) == ("implicitfast", 2e-3, 9e-4)
    assert [(c["integrator"], c["timestep"]) for c in ch.candidates] == [  # the cheaper integrator, not the
        ("implicitfast", 2e-3), ("implicitfast", 1e-3), ("euler", 1e-3), ("rk4", 1e-3)]  # more accurate one
    assert choose(cells, 1e-6).integrator is None
    with pytest.raises(InputError, match="no nominal"):
        choose([dataclasses.replace(cells[0], group="extreme")], 1e-3)


def test_bad_config_is_named():
    with pytest.raises(ConfigError, match="verlet"):
        StabilityConfig(integrators=["verlet"])
    with pytest.raises(ConfigError, match="timesteps"):
        StabilityConfig(timesteps=[0.0])
    with pytest.raises(ConfigError, match="tolerance"):
        StabilityConfig(tolerance=-1.0)


def test_twin_case_converges_with_the_timestep():
    model = F.kitchen()
    m = compile_spec(build_spec(model))
    parts = [p for p in F.parts_of(model).parts if p.articulated]
    c = twin_case(m, parts, duration=0.5)
    assert c.columns == [p.id for p in parts] and c.group == "nominal"
    ref = reference_trace(c)
    e = [run_cell(c, "implicitfast", dt, ref).error for dt in (4e-3, 2e-3, 1e-3)]
    assert e[0] > e[1] > e[2] > 0 and e[2] < 1e-3  # first order: halves with the timestep
    assert e[0] / e[1] == pytest.approx(2.0, rel=0.35)
    with pytest.raises(InputError, match="no articulated"):
        twin_case(m, [])


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    """The stage on the tiny kitchen, every case cut to 0.3 simulated s (the references' cost)."""
    import drawer_lib.stability.pipeline as ss

    mp = pytest.MonkeyPatch()
    short = lambda c: dataclasses.replace(c, duration=min(c.duration, 0.3))  # noqa: E731
    mp.setattr(ss, "extreme_cases", lambda: [short(c) for c in extreme_cases()])
    mp.setattr(ss, "twin_case", lambda m, parts: twin_case(m, parts, duration=0.3))
    d = tmp_path_factory.mktemp("stab")
    model = F.kitchen()
    write_mjcf(build_spec(model), d / "twin")
    write_parts(d / "parts.json", F.parts_of(model))
    (d / "out").mkdir()
    cfg = StabilityConfig(integrators=["euler", "implicitfast", "rk4"], timesteps=[1e-3, 2e-3, 5e-3], extremes=True,
                          rtf_time=0.2)
    run = StageRun("stability", d / "out", d / "out", 0)
    try:
        yield d, run_stability(cfg, d / "parts.json", d / "twin", ("implicitfast", 0.002), run)
    finally:
        mp.undo()


def test_stage_writes_the_matrix_heatmap_and_choice(stage):
    d, m = stage
    rows = read_matrix(d / "out" / "matrix.csv")
    n_parts = len([p for p in F.parts_of(F.kitchen()).parts if p.articulated])
    assert len(rows) == 3 * 3 * (n_parts + len(extreme_cases()))  # the twin's parts one row each
    assert {r["case"] for r in rows} >= {"twin_parts/drawer_0", "stiff_joint", "contact_rich"}
    assert (d / "out" / "heatmap.png").stat().st_size > 10_000
    ch = read_choice(d / "out" / "choice.json")
    assert ch["integrator"] == m["integrator"] and ch["timestep"] == m["timestep"]
    # the choice passes every part within the tolerance, and no larger timestep does
    mine = [r for r in rows if r["case"].startswith("twin_parts/") and r["integrator"] == ch["integrator"]
            and r["timestep"] == ch["timestep"]]
    assert all(not r["diverged"] and r["error"] <= 1e-3 for r in mine)
    bigger = [r for r in rows if r["case"].startswith("twin_parts/") and r["timestep"] > ch["timestep"]]
    assert all(r["diverged"] or r["error"] > 1e-3 for r in bigger) or not bigger
    # the stiff joint is outside what the choice handles, with a remedy
    out = {o["case"]: o for o in ch["outside"]}
    assert out["stiff_joint"]["diverged"] and out["stiff_joint"]["remedy"]["armature"] is not None
    assert m["realtime_factor"] > 1 and m["n_cells_diverged"] > 0


def test_the_matrix_does_not_depend_on_the_number_of_workers():
    """Forked workers (one case each at a time) give the cells of the serial loop, in its order,
    up to the measured wall time."""
    from drawer_lib.stability.pipeline import run_matrix_parallel

    cases = [dataclasses.replace(c, duration=min(c.duration, 0.2)) for c in extreme_cases()[:4]]
    cfg = dict(integrators=["euler", "implicitfast"], timesteps=[1e-3, 5e-3])
    drop = lambda cells: [dataclasses.replace(c, wall_per_sim_s=0.0) for c in cells]  # noqa: E731
    serial, _ = run_matrix_parallel(StabilityConfig(**cfg, workers=1), cases, lambda it, **kw: it)
    forked, _ = run_matrix_parallel(StabilityConfig(**cfg, workers=2), cases, lambda it, **kw: it)
    assert len(serial) == 4 * 2 * 2 and drop(forked) == drop(serial)


def test_stage_choice_is_what_simulate_runs_with(stage, tmp_path):
    from drawer_lib.simulate.pipeline import SimulateConfig, run_simulate

    d, m = stage
    run = StageRun("simulate", tmp_path, tmp_path, 0)
    sm = run_simulate(SimulateConfig(samples=10, interactions=False), d / "parts.json", d / "twin", run,
                      d / "out" / "choice.json")
    assert (sm["integrator"], sm["timestep"]) == (m["integrator"], m["timestep"])
    with pytest.raises(InputError, match="stability"):
        run_simulate(SimulateConfig(samples=10, interactions=False), d / "parts.json", d / "twin", run,
                     tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"integrator": "verlet", "timestep": 1e-3}))
    with pytest.raises(InputError, match="verlet"):
        read_choice(bad)
