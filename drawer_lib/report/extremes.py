"""The numerical-extremes table of the report: every numerically delicate input the pipeline
meets, the test that checks it, and that test's result *now* (the tests are run by
:func:`run_extremes`, never copied from an earlier run).

:data:`ROWS` is the table: (extreme, what must hold, pytest node id). A test
(``tests/test_report.py``) checks that every node id still names a collected test.
"""

import json
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass
from pathlib import Path

from drawer_lib.errors import InputError
from drawer_lib.paths import LAYOUT

DIR = "extremes"  # the stage's folder inside reports/

ROWS: tuple[tuple[str, str, str], ...] = (
    ("SDF density at β = 1e-5, |s| = 1e3", "density and its gradient finite, σ → 1/β inside, 0 outside",
     "tests/sdf/test_render_numerics.py::test_density_finite_with_finite_grads_at_extremes[1e-05]"),
    ("volume-rendering weights at σ up to 1e5, δ from 1e-6 to 10", "weights finite, in [0, 1], gradients finite",
     "tests/sdf/test_render_numerics.py::test_weights_extreme_inputs_finite_and_sum_at_most_one"),
    ("Gaussians with scales 1e-9 and 1e3 (float32)", "image, depth, alpha and every gradient finite",
     "tests/splat/test_rasterize.py::test_extreme_scales_are_finite[dtype0]"),
    ("Gaussians with scales 1e-9 and 1e3 (float64)", "image, depth, alpha and every gradient finite",
     "tests/splat/test_rasterize.py::test_extreme_scales_are_finite[dtype1]"),
    ("Gaussians on and behind the camera plane", "culled (radius 0), zero gradient, no NaN",
     "tests/splat/test_rasterize.py::test_gaussians_on_and_behind_the_camera_plane_are_culled_without_nan"),
    ("an edge-on disc (near-singular 2D covariance)", "rendered, finite",
     "tests/splat/test_rasterize.py::test_near_singular_2d_covariance_edge_on_disc"),
    ("STE at its bound", "forward = the clip, gradient passes (1)",
     "tests/splat/test_anchored.py::test_clip_through_modes"),
    ("STE 1e6 beyond its bound", "forward exactly the clip, gradient 1",
     "tests/splat/test_anchored.py::test_ste_forward_value_is_exactly_the_clip_far_outside_the_bound"),
    ("zero-area faces (Gaussians on the mesh)", "skipped with no NaN frame",
     "tests/splat/test_anchored.py::test_face_frames_embed_the_triangle_and_skip_degenerate_faces"),
    ("tiny (1e-6 m) and huge (1e3 m) faces", "frames and Gaussians finite",
     "tests/splat/test_anchored.py::test_tiny_and_huge_faces_are_handled"),
    ("zero-area faces and a zero-width range (the cut)", "faces assigned, the sweep has one pose",
     "tests/complete/test_complete_cut.py::test_zero_area_faces_and_zero_range_limits"),
    ("zero-area faces (geometry noise)", "vertices stay put, no NaN",
     "tests/test_perturb.py::test_zero_area_faces_and_unreferenced_vertices_stay_put_without_nan"),
    ("an empty mask (marching cubes)", "an empty mesh, no error",
     "tests/mesh/test_extract_clean_metrics.py::test_no_crossing_or_empty_mask_gives_an_empty_mesh"),
    ("an empty part mask (opened-state PSNR)", "the region PSNR is None, not NaN",
     "tests/twin/test_opened_reference.py::test_region_psnr_of_an_empty_mask_is_none"),
    ("degenerate point sets (Umeyama alignment)", "a clear error or the identity, no NaN",
     "tests/sfm/test_align.py::test_umeyama_degenerate_inputs"),
    ("a stiff joint (1e4 N·m/rad on 1e-3 kg·m²)", "diverges once ω dt > 2, caught by the signals",
     "tests/stability/test_study.py::test_stiff_joint_diverges_on_every_integrator_once_w_dt_passes_2"),
    ("heavy damping, tiny armature", "RK4 diverges, MuJoCo's Euler family stays within 1e-3",
     "tests/stability/test_study.py::test_heavy_damping_and_tiny_armature_break_rk4_only"),
    ("a 2 cm drawer in the twin", "driven open stably",
     "tests/sim/test_sim_checks.py::test_tiny_part_drives_stably"),
    ("a diverging simulation", "caught through MuJoCo's warning counters",
     "tests/sim/test_sim_checks.py::test_unstable_simulation_is_caught_through_the_warning_counters"),
)


@dataclass
class ExtremeResult:
    extreme: str
    expect: str
    test: str
    outcome: str  # passed | failed | error | skipped | not run
    seconds: float | None
    message: str | None


def _junit(path: Path) -> dict[str, tuple[str, float, str | None]]:
    """{node id: (outcome, seconds, message)} from pytest's JUnit XML."""
    out = {}
    for tc in ET.parse(path).getroot().iter("testcase"):
        cls, name = tc.get("classname", ""), tc.get("name", "")
        node = cls.replace(".", "/") + ".py::" + name
        outcome, msg = "passed", None
        for tag in ("failure", "error", "skipped"):
            el = tc.find(tag)
            if el is not None:
                outcome = {"failure": "failed"}.get(tag, tag)
                msg = (el.get("message") or "").splitlines()[0][:200] if el.get("message") else None
        out[node] = (outcome, float(tc.get("time", 0.0)), msg)
    return out


def run_extremes(root: Path, scratch: Path, timeout: float = 900.0) -> list[ExtremeResult]:
    """Run every test of :data:`ROWS` (one pytest process, from the project ``root``) and
    return the table with each test's outcome. ``scratch``: a folder for pytest's report."""
    root, scratch = Path(root), Path(scratch)
    if not (root / "tests").is_dir():
        raise InputError(f"{root}/tests: missing (the report runs the numerical-extremes tests from the project root)")
    scratch.mkdir(parents=True, exist_ok=True)
    xml = scratch / "extremes_junit.xml"
    ids = list(dict.fromkeys(r[2] for r in ROWS))
    # pytest refuses a whole run when one node id is unknown: collect the files first, run the ids found
    files = list(dict.fromkeys(i.split("::")[0] for i in ids if (root / i.split("::")[0]).is_file()))
    col = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", *files],
                         cwd=root, capture_output=True, text=True, timeout=timeout) if files else None
    known = set(col.stdout.split()) if col is not None else set()
    ids = [i for i in ids if i in known]
    if not ids:
        return [ExtremeResult(e, x, t, "not run", None, "not collected: the test id is stale") for e, x, t in ROWS]
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={xml}", "-o",
           "junit_family=xunit1", *ids]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=root, capture_output=True, text=True, timeout=timeout)
    if not xml.is_file():
        raise InputError(f"the numerical-extremes tests did not run ({time.perf_counter() - t0:.0f} s, exit "
                         f"{r.returncode}):\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}")
    got = _junit(xml)
    xml.unlink()
    res = []
    for extreme, expect, test in ROWS:
        outcome, sec, msg = got.get(test, ("not run", None, "not collected: the test id is stale"))
        res.append(ExtremeResult(extreme, expect, test, outcome, sec, msg))
    return res


def as_dicts(rows: list[ExtremeResult]) -> list[dict]:
    return [asdict(r) for r in rows]


def extremes_stage(root: Path, reports: Path, enabled: bool = True, timeout: float = 900.0) -> dict:
    """The ``extremes`` stage: run the tests of :data:`ROWS` from the project ``root`` (unless
    ``enabled`` is false) and write ``<reports>/extremes/table.json`` (``extremes_passed``,
    ``extremes_n``, ``rows``, ``wall_s``; ``skipped`` when not run), swapped in whole. A stage of
    its own, so the report does not rerun the tests when only metrics changed, and the tests do
    not wait for the pipeline (they depend on the code and the tests alone)."""
    import tempfile

    from drawer_lib.io.images import write_json
    from drawer_lib.runner import peak_rss_mb

    t0 = time.perf_counter()
    why = None if enabled else "report.extremes = false"
    rows: list[dict] = []
    if enabled:
        with tempfile.TemporaryDirectory() as scratch:
            rows = as_dicts(run_extremes(root, Path(scratch), timeout))
    m = {"extremes_passed": sum(r["outcome"] == "passed" for r in rows), "extremes_n": len(rows), "rows": rows,
         "wall_s": round(time.perf_counter() - t0, 3), "peak_rss_mb": round(peak_rss_mb(), 1)}
    if why:
        m["skipped"] = {"extremes": why}
    path = Path(reports) / DIR / LAYOUT["report"]["table_json"]
    write_json(path, m)  # atomic: a temporary sibling renamed into place
    return m


def read_extremes(reports: Path) -> tuple[list[dict] | None, str | None]:
    """(rows, why not) from the ``extremes`` stage's table: rows None with the reason when the
    tests were not run or the stage has not run."""
    path = Path(reports) / DIR / LAYOUT["report"]["table_json"]
    try:
        m = json.loads(path.read_text())
    except FileNotFoundError:
        return None, f"{path}: missing (the extremes stage has not run)"
    why = (m.get("skipped") or {}).get("extremes")
    return (None, why) if why else (m["rows"], None)
