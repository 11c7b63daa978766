"""Slow (`pytest -m slow`): the neural SDF's default schedule on a capture with 4x kitchen_small's
pixels (kitchen_wide: a 5 m cabinet run, 320x240 x 75 frames, exact depth) reaches the geometry
targets, mesh F@2cm >= 0.95 and Chamfer-L1 <= 5 mm, within the default step count
(the one the 300 s budget is set for; the time itself is reported, not asserted: it depends on
the machine's load)."""

import json
import os
import subprocess
import sys

import pytest
from helpers import ROOT, compose_cfg, load_scene

from drawer_lib.paths import ScenePaths

pytestmark = pytest.mark.slow

FRAMES = 75


def run(module, out, *extra):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-m", f"stages.{module}", "scene=kitchen_wide", f"paths.out={out}", *extra],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=3600)
    assert r.returncode == 0, r.stderr[-3000:]


def test_default_schedule_meets_the_targets_on_a_capture_4x_kitchen_small(tmp_path):
    small, wide = load_scene("kitchen_small").synth.camera, load_scene("kitchen_wide").synth.camera
    assert wide.width * wide.height * FRAMES >= 4 * small.width * small.height * small.n_frames
    out = tmp_path / "out"
    run("capture", out, "capture/depth=exact", f"scene.synth.camera.n_frames={FRAMES}")
    run("priors", out)
    run("sdf", out, "sdf.neural.eval_every=100000")  # the quick probe at the end only
    run("mesh", out)
    sp = ScenePaths(out, "kitchen_wide")
    sdf = json.loads(sp.metrics("sdf").read_text())
    mesh = json.loads(sp.metrics("mesh").read_text())
    steps = compose_cfg(["scene=kitchen_wide"]).sdf.neural.steps
    assert sdf["steps"] == steps and not sdf["stopped_by_time"] and sdf["depth_source"] == "sensor"
    print(f"train_s {sdf['train_s']} for {steps} steps; mesh chamfer {mesh['chamfer_l1']:.4f} m, "
          f"F@1cm {mesh['fscore_1cm']:.3f}, F@2cm {mesh['fscore_2cm']:.3f}")
    assert mesh["fscore_2cm"] >= 0.95 and mesh["chamfer_l1"] <= 0.005, mesh
