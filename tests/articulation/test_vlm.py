"""The ``vlm`` estimator: replies parsed to labels, the votes they add, the view a front is shown
in and its outlined crop, on analytic fixtures; the articulate stage end to end on a tiny
random-weight LLaVA (tiny_hf.py) whose reply is known; a missing model is one line and no
output; configurations that would lose the answer are refused."""

import json
import shutil

import numpy as np
import pytest
from helpers import add_overlays, gt_mesh_project, run_stage, scene_paths

from drawer_lib.articulation.config import ArticulateConfig, TypesConfig, VlmConfig
from drawer_lib.articulation.estimators import get_estimator
from drawer_lib.articulation.rectify import View
from drawer_lib.articulation.vlm import RED, VlmTyper, best_view, outlined_crop, parse_answer, vlm_parts, vote
from drawer_lib.errors import ConfigError
from drawer_lib.geometry.camera import Camera, Intrinsics
from drawer_lib.hub import HubModel

ANSWERS = VlmConfig().answers


@pytest.mark.parametrize("reply, label", [
    ("Drawer.", "drawer"), ("It is a door, not a drawer", "door"), ("doors", "door"), ("a DRAWERS", "drawer"),
    ("A fixed panel", "front"), ("a lid that flips up", "door"), ("doorway", None), ("", None), ("cupboard", None),
])
def test_a_reply_gives_the_label_of_its_first_answer_word(reply, label):
    assert parse_answer(reply, ANSWERS) == label


def test_the_answer_holds_its_share_of_the_votes():
    assert vote({}, "drawer", 0.5) == {"drawer": 1}  # no detection votes: the answer alone
    assert vote({"front": 10}, "drawer", 0.5) == {"front": 10, "drawer": 10}
    assert vote({"front": 10}, "drawer", 0.75) == {"front": 10, "drawer": 30}
    assert vote({"door": 3, "drawer": 1}, "drawer", 0.2) == {"door": 3, "drawer": 2}
    assert vote({"front": 4}, "door", 0.5) == {"front": 4, "door": 4}


def _view(z: float, depth: float = 0.0, size: int = 100, image: bool = True) -> View:
    """A camera at the origin looking down +z, the world shifted by ``z`` along it; ``depth``:
    the ray-cast depth everywhere (0: no surface)."""
    intr = Intrinsics(fx=100.0, fy=100.0, cx=size / 2, cy=size / 2, width=size, height=size)
    w2c = np.eye(4)
    w2c[2, 3] = z
    img = np.zeros((size, size, 3), np.uint8) if image else None
    return View(Camera(intr, w2c), np.full((size, size), depth), image=img, stem=f"z{z}")


SQUARE = np.array([[x, y, 0.0] for x in np.linspace(-0.2, 0.2, 5) for y in np.linspace(-0.2, 0.2, 5)])


def test_the_front_is_shown_in_the_view_that_sees_it_largest_and_whole():
    far, near = _view(2.0), _view(1.0)
    k, box = best_view(SQUARE, [far, near], min_px=4)
    assert k == 1 and box == (30, 30, 70, 70)  # 0.4 m at 1 m and f = 100 px: 40 px
    assert best_view(SQUARE, [far], min_px=4) == (0, (40, 40, 60, 60))
    assert best_view(SQUARE, [far, _view(0.4)], min_px=4)[0] == 1  # 100 px: the image's whole width
    assert best_view(SQUARE, [far, _view(0.3)], min_px=4)[0] == 0  # nearer, the border cuts it off
    dense = np.array([[x, y, 0.0] for x in np.linspace(-0.2, 0.2, 11) for y in np.linspace(-0.2, 0.2, 11)])
    shifted = _view(1.0)
    shifted.camera.w2c[0, 3] = 0.35  # its 2 right columns (18 %) out of the image: not whole enough
    assert best_view(dense, [far, shifted], min_px=4)[0] == 0
    shifted.camera.w2c[0, 3] = 0.31  # 1 column (9 %) out: shown, its box cut at the border
    assert best_view(dense, [far, shifted], min_px=4) == (1, (61, 30, 100, 70))
    assert best_view(SQUARE, [far, _view(1.0, depth=0.5)], min_px=4)[0] == 0  # something nearer hides it
    assert best_view(SQUARE, [far, _view(1.0, depth=1.0)], min_px=4)[0] == 1  # the surface is the front itself
    assert best_view(SQUARE, [_view(-1.0)], min_px=4) is None  # behind the camera
    assert best_view(SQUARE, [far, near], min_px=50) is None  # too small in every view
    assert best_view(SQUARE, [_view(1.0, image=False)], min_px=4) is None
    assert best_view(SQUARE[:0], [near], min_px=4) is None


def test_the_crop_keeps_its_margin_and_outlines_the_box_in_red():
    img = np.zeros((100, 100, 3), np.uint8)
    c = outlined_crop(img, (40, 40, 60, 60), margin=0.5)
    assert c.shape == (40, 40, 3)
    assert (c[10, 10:30] == RED).all() and (c[29, 10:30] == RED).all() and (c[10:30, 10] == RED).all()
    assert (c[12:28, 12:28] == 0).all() and (c[:9] == 0).all()  # inside and outside the outline untouched
    c = outlined_crop(img, (0, 90, 30, 100), margin=0.5)  # at the image's corner: clipped
    assert c.shape == (15, 45, 3) and (c[5, :30] == RED).all()
    assert (img == 0).all()  # the view's image is not drawn on


def test_configurations_that_would_lose_the_answer_are_refused():
    with pytest.raises(ConfigError, match="use_labels"):
        ArticulateConfig(estimator="vlm", types=TypesConfig(use_labels=False))
    with pytest.raises(ConfigError, match="not front labels"):
        ArticulateConfig(estimator="vlm", vlm=VlmConfig(answers={"object": ["box"]}))
    ArticulateConfig(vlm=VlmConfig(answers={"object": ["box"]}))  # only the vlm estimator reads them
    with pytest.raises(ConfigError, match="share"):
        VlmConfig(share=1.0)
    with pytest.raises(ConfigError, match="prompt"):
        VlmConfig(prompt=" ")
    with pytest.raises(ConfigError, match="set by the estimator"):
        VlmConfig(processor_kwargs={"images": []})
    assert get_estimator("vlm") is vlm_parts


@pytest.mark.parametrize("family", ["llava", "idefics3"])
def test_the_model_answers_an_image_through_its_own_processor(family, tmp_path):
    pytest.importorskip("transformers")
    import tiny_hf

    d = getattr(tiny_hf, f"tiny_{family}")(tmp_path / family)
    typer = VlmTyper(VlmConfig(model=HubModel("none/none", path=str(d)), max_new_tokens=3))
    img = (np.random.default_rng(0).random((40, 70, 3)) * 255).astype(np.uint8)
    reply, n = typer.ask(img)
    assert reply == "drawer drawer drawer" and parse_answer(reply, ANSWERS) == "drawer"
    assert typer.ask(img[:9, :30])[0] == reply  # a crop smaller than the model's tiles
    # the processor's keywords reach it: Idefics3 tiles the image only when asked to (one 32 px
    # image of 4 tokens, or 2 x 2 tiles and the global image of 4 each, each tile with its
    # <fake_token_around_image><row_i_col_j> marker: 16 + 8 more tokens); LLaVA ignores the key
    split = VlmTyper(VlmConfig(model=HubModel("none/none", path=str(d)), max_new_tokens=3,
                               processor_kwargs={"do_image_splitting": True}))
    reply_split, n_split = split.ask(img)
    assert reply_split == reply
    assert n_split - n == (24 if family == "idefics3" else 0)


@pytest.mark.gpu
@pytest.mark.parametrize("family", ["llava", "idefics3"])
def test_the_model_answers_on_cuda_as_on_the_cpu(family, tmp_path):
    """``articulate.vlm.device: cuda``: the processor's tensors reach the card and the reply and
    its cost in tokens are the CPU's."""
    pytest.importorskip("transformers")
    import tiny_hf

    d = getattr(tiny_hf, f"tiny_{family}")(tmp_path / family)
    img = (np.random.default_rng(0).random((40, 70, 3)) * 255).astype(np.uint8)
    cpu, gpu = (VlmTyper(VlmConfig(model=HubModel("none/none", path=str(d)), max_new_tokens=3, device=dev)).ask(img)
                for dev in ("cpu", "cuda"))
    assert gpu == cpu and gpu[0] == "drawer drawer drawer"


@pytest.fixture()
def project(tmp_path, exact_capture):
    gt_mesh_project(tmp_path, exact_capture[0])
    add_overlays(tmp_path, priors=False)
    r = run_stage("decompose", tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    return tmp_path


PRIOR = "articulate.types.weights=prior"


def test_articulate_asks_a_tiny_vlm_about_every_front(project, tmp_path_factory):
    pytest.importorskip("transformers")
    from tiny_hf import tiny_llava

    model = tiny_llava(tmp_path_factory.mktemp("hf") / "llava")
    r = run_stage("articulate", project, PRIOR, "articulate.estimator=vlm", f"articulate.vlm.model.path={model}",
                  "articulate.vlm.min_px=8")  # the tiny kitchen's 96 x 72 views
    assert r.returncode == 0, r.stderr[-3000:]
    sp = scene_paths(project)
    assert json.loads(sp.metrics("articulate").read_text())["estimator"] == "vlm"
    dec = json.loads(sp.file("articulate", "decisions").read_text())
    asked = [s for s in dec["segments"] if "vlm" in s]
    assert asked and dec["estimator"] == "vlm"
    stems = {p.stem for p in (sp.capture / "images").iterdir()}
    for s in asked:  # the tiny model always answers "drawer"
        v = s["vlm"]
        assert v["reply"].split()[0] == "drawer" and v["label"] == "drawer" and v["view"] in stems
        assert v["tokens"] > 16  # the image's 16 tokens and the prompt's
        x0, y0, x1, y1 = v["box"]
        assert 0 <= x0 and x1 - x0 >= 8 and 0 <= y0 and y1 - y0 >= 8
    scored = [s for s in asked if "features" in s]  # the fronts the score rule typed
    assert scored and all(s["features"]["lab_drawer"] >= 0.5 for s in scored)  # the answer holds half the votes
    shutil.rmtree(sp.stage_dir("articulate"))
    r = run_stage("articulate", project, PRIOR)  # the geometric estimator asks nothing
    dec = json.loads(sp.file("articulate", "decisions").read_text())
    assert r.returncode == 0 and not any("vlm" in s for s in dec["segments"])


def test_a_missing_vlm_is_one_line_and_writes_nothing(project, tmp_path):
    r = run_stage("articulate", project, PRIOR, "articulate.estimator=vlm",
                  f"articulate.vlm.model.path={tmp_path / 'nowhere'}")
    last = r.stderr.strip().splitlines()[-1]
    assert r.returncode == 2 and last.startswith("error: articulate.vlm.model.path") and "hf download" in last
    assert not scene_paths(project).stage_dir("articulate").exists()
