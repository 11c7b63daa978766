"""The ``vlm`` estimator: the geometric estimator with a vision-language model's answer for each
front. DRAWER shows GPT-4o each part and asks what it is; here a model that runs locally
through ``transformers`` (``AutoModelForImageTextToText``: SmolVLM, LLaVA, Qwen2-VL, ...) is
shown each segment in the view that sees it largest, outlined in red, and its one-word answer
becomes label votes of the segment (``articulate.vlm``, :class:`VlmConfig`). The votes enter
the score rule as the detections' labels do (``lab_drawer``, ``lab_door``), so the handle, the
layout and the geometry still decide with them; ``decisions.json`` records, for every segment
asked, the view, the reply and the label it gave.

Weights are read from a local folder or the Hugging Face cache and never fetched unless
``articulate.vlm.allow_download`` is set; a missing model is one line naming the command that
fetches it."""

import dataclasses
import re

import numpy as np
import torch
import trimesh
from jaxtyping import Float
from tqdm import tqdm

from drawer_lib.articulation.config import ArticulateConfig, VlmConfig
from drawer_lib.articulation.infer import infer_parts
from drawer_lib.articulation.rectify import View
from drawer_lib.devices import torch_device
from drawer_lib.errors import InputError, NonFiniteError
from drawer_lib.hub import model_dir
from drawer_lib.io.parts import Part
from drawer_lib.perception.decompose import Segment

RED = np.array([255, 0, 0], np.uint8)


def parse_answer(reply: str, answers: dict[str, list[str]]) -> str | None:
    """The label (a key of ``answers``) whose word comes first in ``reply`` (whole words,
    any case, a plural ``s`` allowed); None when no word is there."""
    best, at = None, len(reply) + 1
    low = reply.lower()
    for label, words in answers.items():
        for w in words:
            m = re.search(rf"\b{re.escape(w.lower())}s?\b", low)
            if m is not None and m.start() < at:
                best, at = label, m.start()
    return best


def best_view(points: Float[np.ndarray, "N 3"], views: list[View], min_px: int, depth_tol: float = 0.03
              ) -> tuple[int, tuple[int, int, int, int]] | None:
    """(index into ``views``, box (x0, y0, x1, y1) in pixels, end-exclusive, within the image)
    of the view with an image that shows ``points`` (a segment's face centres, m) largest: every
    point in front of the camera, at least 90 % of them inside the image and 80 % not hidden
    (their depth within ``depth_tol`` + 2 % of the view's ray-cast depth), the box's shorter
    side at least ``min_px``. None when no view does."""
    best, best_area = None, 0.0
    for k, v in enumerate(views):
        if v.image is None or len(points) == 0:
            continue
        uv, z = v.camera.project(points)
        H, W = v.image.shape[:2]
        if not (np.all(z > 1e-6) and np.all(np.isfinite(uv))):
            continue
        inside = (uv[:, 0] >= 0) & (uv[:, 1] >= 0) & (uv[:, 0] <= W) & (uv[:, 1] <= H)
        if inside.mean() < 0.9:
            continue
        ii = np.clip(uv[:, 1].astype(int), 0, H - 1)
        jj = np.clip(uv[:, 0].astype(int), 0, W - 1)
        d = v.depth[ii, jj]
        seen = inside & ((d <= 0) | (z <= d + depth_tol + 0.02 * d))
        if seen.mean() < 0.8:
            continue
        x0, y0 = np.maximum(np.floor(uv.min(0)).astype(int), 0)
        x1, y1 = np.minimum(np.ceil(uv.max(0)).astype(int), [W, H])
        if min(x1 - x0, y1 - y0) < min_px:
            continue
        area = float((x1 - x0) * (y1 - y0))
        if area > best_area:
            best, best_area = (k, (int(x0), int(y0), int(x1), int(y1))), area
    return best


def outlined_crop(image: np.ndarray, box: tuple[int, int, int, int], margin: float) -> np.ndarray:
    """The part of ``image`` (uint8 [H, W, 3]) around ``box`` with ``margin`` x its size on every
    side (clipped to the image), the box outlined in red 2 px wide (of at most a quarter of its
    shorter side)."""
    H, W = image.shape[:2]
    x0, y0, x1, y1 = box
    mx, my = int(round(margin * (x1 - x0))), int(round(margin * (y1 - y0)))
    cx0, cy0, cx1, cy1 = max(0, x0 - mx), max(0, y0 - my), min(W, x1 + mx), min(H, y1 + my)
    out = image[cy0:cy1, cx0:cx1].copy()
    bx0, by0, bx1, by1 = x0 - cx0, y0 - cy0, min(x1, W) - cx0, min(y1, H) - cy0
    t = max(1, min(2, (min(bx1 - bx0, by1 - by0)) // 4))
    out[by0:by1, bx0:bx0 + t] = RED
    out[by0:by1, bx1 - t:bx1] = RED
    out[by0:by0 + t, bx0:bx1] = RED
    out[by1 - t:by1, bx0:bx1] = RED
    return out


class VlmTyper:
    """A vision-language model from ``cfg.model``, asked one image at a time."""

    def __init__(self, cfg: VlmConfig):
        from transformers import AutoModelForImageTextToText, AutoProcessor

        self.cfg = cfg
        d = model_dir(cfg.model, cfg.allow_download, "articulate.vlm.model")
        self.device = torch_device(cfg.device, "articulate.vlm.device")
        self.proc = AutoProcessor.from_pretrained(d, local_files_only=True)
        self.model = AutoModelForImageTextToText.from_pretrained(d, local_files_only=True).eval().to(self.device)
        if getattr(self.proc, "chat_template", None) is None:
            raise InputError(f"articulate.vlm.model: {d} has no chat template (an instruction-tuned model has one)")

    @torch.inference_mode()
    def ask(self, image: np.ndarray) -> tuple[str, int]:
        """The model's reply (greedy decoding) to ``cfg.prompt`` about uint8 [H, W, 3] ``image``,
        and the length of its input in tokens (the image's tokens and the prompt's: its cost)."""
        from PIL import Image

        msgs = [{"role": "user", "content": [{"type": "image"}, {"type": "text", "text": self.cfg.prompt}]}]
        text = self.proc.apply_chat_template(msgs, add_generation_prompt=True)
        inp = self.proc(text=text, images=[Image.fromarray(image)], return_tensors="pt",
                        **self.cfg.processor_kwargs).to(self.device)
        pv = inp.get("pixel_values")
        if pv is not None and not torch.isfinite(pv).all():
            raise NonFiniteError("articulate.vlm: the processor gave non-finite pixel values")
        out = self.model.generate(**inp, max_new_tokens=self.cfg.max_new_tokens, do_sample=False)
        n = int(inp["input_ids"].shape[1])
        return self.proc.batch_decode(out[:, n:], skip_special_tokens=True)[0].strip(), n


def vote(labels: dict[str, int], label: str, share: float) -> dict[str, int]:
    """``labels`` with ``label``'s votes raised by ``share`` / (1 - ``share``) x their total (at
    least 1): the answer holds ``share`` of the votes it adds to."""
    out = dict(labels)
    add = max(1, int(round(share / (1.0 - share) * sum(labels.values()))))
    out[label] = out.get(label, 0) + add
    return out


def vlm_parts(mesh: trimesh.Trimesh, segs: list[Segment], cam_centers: np.ndarray, cfg: ArticulateConfig, *,
              vlm_views: list[View], typer: VlmTyper | None = None, **kw) -> tuple[list[Part], list[dict]]:
    """:func:`~drawer_lib.articulation.infer.infer_parts` on ``segs`` whose planar segments
    carry the model's answer as label votes. ``vlm_views``: the train views with their images
    and ray-cast depth; ``typer``: the model (None: loaded from ``cfg.vlm``); ``kw``: the
    rest of ``infer_parts``'s arguments."""
    vc = cfg.vlm
    if not any(v.image is not None for v in vlm_views):
        raise InputError("articulate.estimator = vlm: the capture's train views have no images")
    typer = typer or VlmTyper(vc)
    centres = np.asarray(mesh.triangles_center)
    asked: dict[int, dict] = {}
    out = []
    for s in tqdm(segs, desc="articulate: vlm", leave=False):
        bv = best_view(centres[s.faces], vlm_views, vc.min_px) if s.planar else None
        if bv is None:
            out.append(s)
            continue
        k, box = bv
        reply, tokens = typer.ask(outlined_crop(vlm_views[k].image, box, vc.margin))
        label = parse_answer(reply, vc.answers)
        asked[s.id] = {"view": vlm_views[k].stem, "box": list(box), "reply": reply, "label": label, "tokens": tokens}
        out.append(dataclasses.replace(s, labels=vote(s.labels, label, vc.share)) if label else s)
    parts, report = infer_parts(mesh, out, cam_centers, cfg, **kw)
    for r in report:
        if r.get("segment") in asked:
            r["vlm"] = asked[r["segment"]]
    return parts, report
