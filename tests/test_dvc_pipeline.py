"""End to end through the dvc CLI in a temporary copy of the project: `dvc repro` builds the
capture of a tiny scene, a second `dvc repro` does nothing, and stages compute from params.yaml
(so `dvc exp run -S` changes what they compute)."""

import html
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from helpers import ROOT

from drawer_lib.articulation.weights import read_weights
from drawer_lib.paths import LAYOUT, BenchPaths, ScenePaths, capture_name

pytestmark = pytest.mark.dvc

_IGNORE_ANYWHERE = shutil.ignore_patterns(".venv", "multirun", "outputs", ".git", "cache", "tmp", "__pycache__",
                                          ".pytest_cache", ".hypothesis", "*.egg-info", "dvc.lock")
_OUTPUT_ROOTS = {"out", "bench", "reports", "logs"}  # generated data, at the project root only (conf/bench is config)


def IGNORE(folder: str, names: list[str]) -> set[str]:
    ignored = set(_IGNORE_ANYWHERE(folder, names))
    if Path(folder).resolve() == ROOT.resolve():
        ignored |= _OUTPUT_ROOTS & set(names)
    return ignored


# the whole DAG on the tiny scene, with the geometry stages shrunk to seconds
FAST_PARAMS = ["scenes=[kitchen_tiny]", "geometry_variants=[tsdf]", "sdf.neural.steps=8", "sdf.neural.eval_every=4",
               "sdf.neural.sampling.groups=2", "sdf.neural.sampling.rays_per_group=32", "mesh.cell=0.04",
               "mesh.eval_points=5000", "appearance.steps=4", "appearance.eval_every=2", "appearance.max_faces=3000",
               "appearance.texture_cell=0.05", "appearance.strategy=null",
               "appearance_variants=[textured_mesh,movable_gs_ste]",
               # an 8-step SDF makes a mesh no twin could pass its physical checks on: the smoke test
               # checks the plumbing (the checks are tested on fixtures, tests/sim, and run on kitchen_small)
               "twin.check=false", "twin.renders.max_views=1", "twin.renders.lpips=false",
               # the stability study on the twin's parts at two timesteps; the report without the extremes' pytest run
               "stability.extremes=false", "stability.timesteps=[0.001,0.002]", "stability.integrators=[implicitfast,euler]",
               "stability.rtf_time=0.2", "report.extremes=false",
               # the robot on two parts, no camera (its physics and dataset: tests/robot)
               "robot.max_parts=2", "robot.camera=[0,0]",
               # the benchmark: kitchen 0 of each split, at kitchen_tiny's frames
               "bench.kitchens=[0]", "bench.hand_kitchens=[0]", "bench.camera={n_frames:12,width:96,height:72}",
               # the built-in detector: a few steps on one train kitchen, a few more averaged (its fit: tests/detect)
               "detector.kitchens=[0]", "detector.eval_kitchens=[0]", "detector.steps=4", "detector.log_every=2",
               "detector.frame_every=12", "detector.average_steps=3", "detector.average_warmup=1"]


def make_repo(tmp_path_factory, params: list[str], prepare=None):
    """A git repository holding a copy of the project with ``params`` composed into params.yaml;
    ``prepare(root)`` adds files first. Returns (root, run)."""
    d = tmp_path_factory.mktemp("repo") / "drawer"
    shutil.copytree(ROOT, d, ignore=IGNORE)
    if prepare is not None:
        prepare(d)
    home = d.parent / "home"
    home.mkdir()
    env = dict(os.environ)
    for k in ("DVC_ROOT", "DVC_STAGE", "DVC_EXP_NAME"):
        env.pop(k, None)
    env.update({
        "HOME": str(home), "GIT_CONFIG_GLOBAL": "/dev/null", "GIT_CONFIG_NOSYSTEM": "1",
        "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t",
        "DVC_SITE_CACHE_DIR": str(d.parent / "site_cache"), "DVC_NO_ANALYTICS": "1",
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{env['PATH']}",
        "PYTHONPATH": str(d),
    })

    def run(*cmd, check=True, cwd=None):
        r = subprocess.run(cmd, cwd=cwd or d, env=env, capture_output=True, text=True, timeout=900)
        if check and r.returncode != 0:
            raise AssertionError(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stdout}\n{r.stderr}")
        return r

    run(sys.executable, "scripts/compose_params.py", *params)
    run("git", "init", "-q", "-b", "main")
    run("git", "add", "-A")
    run("git", "commit", "-qm", "init")
    return d, run


@pytest.fixture(scope="module")
def repo(tmp_path_factory):
    return make_repo(tmp_path_factory, FAST_PARAMS)


def test_repro_builds_capture_then_does_nothing(repo):
    d, run = repo
    r = run("dvc", "repro")
    sp = ScenePaths(d / "out", "kitchen_tiny")
    cap = sp.capture
    for key in ("transforms", "manifest", "images", "depth", "gt_parts", "gt_mesh"):
        assert (cap / capture_name(key)).exists(), key
    m = json.loads(sp.metrics("capture").read_text())
    assert m["n_frames"] == 12 and "wall_s" in m
    import mujoco

    twin = sp.stage_dir("twin")
    model = mujoco.MjModel.from_xml_path(str(twin / "scene.xml"))  # loads with nothing but twin/
    parts = json.loads((twin / "twin.json").read_text())["parts"]
    for p in parts:
        if p["kind"] in ("revolute", "prismatic"):
            assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, p["id"]) >= 0, p["id"]
    assert (twin / "urdf" / "scene.urdf").is_file() and (twin / "scene.usda").is_file()
    stamp = sp.metrics("capture").stat().st_mtime_ns
    r = run("dvc", "repro")
    assert "Data and pipelines are up to date." in r.stdout
    assert "Running stage" not in r.stdout
    assert sp.metrics("capture").stat().st_mtime_ns == stamp
    shown = json.dumps(json.loads(run("dvc", "metrics", "show", "--json").stdout))
    assert "n_frames" in shown and "fscore_2cm" in shown and "chamfer_l1" in shown
    tsdf = ScenePaths(d / "out", "kitchen_tiny", "tsdf")
    for p in (sp.field, sp.stage_dir("sdf") / LAYOUT["curve"], sp.mesh, tsdf.metrics("mesh")):
        assert p.exists(), p
    table = json.loads((d / "reports" / "geometry" / LAYOUT["report"]["table_json"]).read_text())
    assert set(table["kitchen_tiny"]) == {"neural (selected)", "tsdf"}
    for p in (sp.file("decompose", "segments"), sp.parts, sp.file("evaluate", "matches")):
        assert p.exists(), p
    ev = json.loads(sp.metrics("evaluate").read_text())
    assert "recall" in ev and ev["n_gt"] > 0
    assert sp.file("simulate", "tracks").exists() and json.loads(sp.metrics("simulate").read_text())["n_parts"] == ev["n_pred"]
    assert "emd" in ev or "emd" in ev["skipped"]
    choice = json.loads(sp.file("stability", "choice").read_text())
    assert choice["integrator"] in ("implicitfast", "euler") and choice["timestep"] in (0.001, 0.002)
    assert json.loads(sp.metrics("simulate").read_text())["timestep"] == choice["timestep"]  # simulate ran with it
    page = (d / "reports" / LAYOUT["report"]["index"]).read_text()
    # the report's stability section shows this run's choice and heat map (the section itself is
    # always there; without the stage's outputs it says "the stability stage has not run")
    section = page.split('<section id="stability">', 1)[1].split("</section>", 1)[0]
    chosen = f"kitchen_tiny: chosen {choice['integrator']} at {choice['timestep']:g} s ({choice['source']})"
    assert html.escape(chosen) in section and 'alt="kitchen_tiny: stability heat map"' in section, section[:2000]
    assert "report.extremes = false" in (d / "reports" / LAYOUT["report"]["summary"]).read_text()
    # every file a stage writes is a declared output: an undeclared one is not pushed to a remote,
    # and a clone that pulls sees out/ differ and reruns every stage that depends on it
    lock = yaml.safe_load((d / "dvc.lock").read_text())["stages"]
    outs = {o["path"].rstrip("/") for st in lock.values() for o in st.get("outs", [])}
    stray = [p.relative_to(d).as_posix() for root in ("out", "bench") for p in (d / root).rglob("*") if p.is_file()
             and not any(p.relative_to(d).as_posix() == o or p.relative_to(d).as_posix().startswith(o + "/")
                         for o in outs)]
    assert not stray, stray
    abl = json.loads((d / "reports" / "ablation" / LAYOUT["report"]["table_json"]).read_text())
    assert set(abl["kitchen_tiny"]) == {"textured_mesh", "movable_gs_ste"}
    assert (sp.appearance_dir("movable_gs_ste") / LAYOUT["appearance"]["model"] / "gaussians.ply").exists()
    # the benchmark: its kitchens, the fitted weights articulate read, every split's table (hand: bench_hand, bench_eval_hand)
    bench = BenchPaths(d / "bench")
    assert read_weights(bench.weights) and json.loads((bench.fit / LAYOUT["metrics"]).read_text())["n_kitchens"] == 1
    assert any(dep["path"] == "bench/fit/weights.json" for dep in lock["articulate@kitchen_tiny"]["deps"])
    assert "bench_hand@0" in lock and "bench_eval_hand" in lock
    for split in ("train", "test", "hand"):
        assert bench.kitchen(split, 0).parts.is_file()
        m = json.loads((bench.eval(split) / LAYOUT["metrics"]).read_text())
        assert m["fitted_n_kitchens"] == 1 and m["fitted_n_gt"] > 0
        assert (bench.eval(split) / LAYOUT["report"]["table"]).read_text().startswith(f"## The {split} split")


def test_stage_reads_params_yaml(repo):
    d, run = repo
    run("dvc", "repro")
    p = yaml.safe_load((d / "params.yaml").read_text())
    p["capture"]["split"]["test_every"] = 3
    (d / "params.yaml").write_text(yaml.safe_dump(p, sort_keys=False))
    st = run("dvc", "status").stdout
    assert "capture@kitchen_tiny" in st and "modified:           capture" in st
    # the capture stage is what reads the key; the whole DAG's rerun is the first test's (this
    # test and the next took ~3 min each when they rebuilt everything downstream)
    run("dvc", "repro", "capture@kitchen_tiny")
    t = json.loads((ScenePaths(d / "out", "kitchen_tiny").capture / capture_name("transforms")).read_text())
    assert len(t["test_filenames"]) == 4  # 12 frames, every 3rd
    run("git", "checkout", "params.yaml")
    run("dvc", "repro", "capture@kitchen_tiny")  # back to the committed params (restored from the run cache)
    assert "capture@kitchen_tiny" not in run("dvc", "status").stdout


def test_exp_run_set_param_changes_the_result(repo):
    d, run = repo
    sets = [a for p in FAST_PARAMS + ["capture.split.test_every=6"] for a in ("-S", p)]
    run("dvc", "exp", "run", *sets, "capture@kitchen_tiny")  # exp run recomposes params.yaml from conf/ + these
    t = json.loads((ScenePaths(d / "out", "kitchen_tiny").capture / capture_name("transforms")).read_text())
    assert len(t["test_filenames"]) == 2
    assert "test_every: 6" in (d / "params.yaml").read_text()


def test_whole_dag_on_a_distorted_nerfstudio_capture(tmp_path_factory, exact_capture):
    """A user's capture as ns-process-data writes it (OPENCV distortion, JPEG, no splits, RGB
    only) and a scene file of two lines: every stage runs, the capture is undistorted, and the
    stages that need what the capture lacks record why they skip."""
    from helpers import write_ns_capture

    def prepare(d):
        write_ns_capture(exact_capture[0], d / "data" / "ns_distorted")
        (d / "conf" / "scene" / "ns_distorted.yaml").write_text("source: dir\ndir: {path: data/ns_distorted}\n")

    params = [p for p in FAST_PARAMS if not p.startswith(("scenes=", "geometry_variants="))]
    # the benchmark's train kitchen only: the fitted weights articulate needs (the test split's table is the first test's)
    d, run = make_repo(tmp_path_factory, params + ["scenes=[ns_distorted]", "geometry_variants=[]", "bench.splits=[train]"],
                       prepare)
    run("dvc", "repro")
    sp = ScenePaths(d / "out", "ns_distorted")
    for p in (sp.capture / capture_name("transforms"), sp.field, sp.mesh, sp.file("decompose", "segments"), sp.parts,
              sp.metrics("evaluate"), sp.appearance_dir("movable_gs_ste") / LAYOUT["appearance"]["model"] / "gaussians.ply",
              sp.appearance_dir("textured_mesh") / LAYOUT["metrics"]):
        assert p.exists(), p
    man = json.loads((sp.capture / capture_name("manifest")).read_text())
    assert man["details"]["intrinsics"]["undistorted"] and man["has"]["depth"] is False
    assert json.loads((sp.capture / capture_name("transforms")).read_text())["camera_model"] == "PINHOLE"
    sdf = json.loads(sp.metrics("sdf").read_text())
    assert "depth_loss" in sdf["skipped"] and "geometry_curve_metrics" in sdf["skipped"]
    det = json.loads(sp.metrics("detect").read_text())  # an RGB-only capture: the built-in detector's masks
    assert det["model"] == "builtin" and det["chosen"] == "auto: the capture has none"
    pri = json.loads(sp.metrics("priors").read_text())
    assert pri["model"] == "none" and not pri["has_mono_depth"]
    ev = json.loads(sp.metrics("evaluate").read_text())
    assert "precision" not in ev and "articulation" in ev["skipped"]
    assert "Data and pipelines are up to date." in run("dvc", "repro").stdout


@pytest.mark.slow
def test_make_run_on_a_video_a_phone_capture_and_a_synthetic_scene(tmp_path_factory, exact_capture):
    """What `make run` runs (scripts/repro.py) on three scenes at once: the synthetic kitchen,
    a phone's RGB-D capture as ns-process-data writes a Polycam one, and a plain H.264 video
    with nothing else. Every scene reaches the twin; the TSDF comparison the video cannot run is
    skipped with its reason, and so is every score that needs ground truth it lacks (~6 min)."""
    from helpers import load_scene, render_capture, sensor_cfg

    from drawer_lib.io.capture import load_capture
    from drawer_lib.sfm.video import write_video
    from drawer_lib.synth.phone import write_polycam

    truth = tmp_path_factory.mktemp("video_truth")
    render_capture(load_scene("kitchen_small"), sensor_cfg(depth="exact", detections="off", mono="off"), truth)
    frames = load_capture(truth)

    def prepare(d):
        write_polycam(exact_capture[0], d / "data" / "phone")
        (d / "conf" / "scene" / "phone.yaml").write_text(
            "source: dir\ndir: {path: data/phone, metric_scale: true, gravity: true}\n")
        write_video(d / "data" / "kitchen.mp4", [frames.image(i) for i in range(len(frames.frames))], fps=10, quality=10)
        (d / "conf" / "scene" / "video.yaml").write_text("source: video\nvideo: {path: data/kitchen.mp4}\n")

    params = [p for p in FAST_PARAMS if not p.startswith("scenes=")]
    d, run = make_repo(tmp_path_factory, params + ["scenes=[kitchen_tiny,phone,video]", "bench.splits=[train]"], prepare)
    r = run(sys.executable, "scripts/repro.py", "--jobs", "2")
    for scene in ("kitchen_tiny", "phone", "video"):
        sp = ScenePaths(d / "out", scene)
        for p in (sp.field, sp.mesh, sp.parts, sp.stage_dir("twin") / "scene.xml", sp.metrics("evaluate")):
            assert p.exists(), (scene, p)
    phone, video = ScenePaths(d / "out", "phone"), ScenePaths(d / "out", "video")
    assert json.loads(phone.metrics("sdf").read_text())["depth_source"] == "sensor"
    assert json.loads(phone.metrics("detect").read_text())["model"] == "builtin"
    tsdf = json.loads(ScenePaths(d / "out", "video", "tsdf").metrics("sdf").read_text())
    assert "needs metric depth" in tsdf["skipped"]["sdf"]
    man = json.loads((video.capture / capture_name("manifest")).read_text())
    assert man["world_frame"]["scale"]["factor"] > 0 and "scale estimated from" in man["world_frame"]["how"]
    ev = json.loads(video.metrics("evaluate").read_text())
    assert "precision" not in ev and "articulation" in ev["skipped"]
    # each handle's standoff: looked for in the metric depth of the synthetic and the phone capture
    # and recorded with its grasp, measured or with why not (these 8-step fields put the phone's
    # fronts centimetres off its depth); a video has no depth to look in
    assert json.loads(video.metrics("complete").read_text())["skipped"]["handle_standoff"] == "the capture has no depth maps"
    for scene in ("kitchen_tiny", "phone"):
        sp = ScenePaths(d / "out", scene)
        cm = json.loads(sp.metrics("complete").read_text())
        handled = [p for p in json.loads((sp.stage_dir("twin") / "twin.json").read_text())["parts"]
                   if (p.get("grasp") or {}).get("kind") == "handle"]
        if not handled:
            assert cm["skipped"]["handle_standoff"] == "no part has handle evidence", scene
            continue
        assert all(p["grasp"]["standoff"]["standoff_m"] is not None or p["grasp"]["standoff"]["why"] for p in handled)
        assert cm["handle_standoff_measured"] + cm["handle_standoff_flush"] + cm["handle_standoff_unmeasured"] == len(handled)
    assert handled  # the phone's twin has handles
    assert "Data and pipelines are up to date." in run("dvc", "repro").stdout, r.stdout[-3000:]
