"""A tiny twin folder for the viewer tests, written directly (no capture, no renders): the
analytic kitchen of tests/sim (a drawer in a carcass, a door, a flap, a counter, two cups) as
``scene.xml`` by the project's MJCF writer, Gaussians covering every collision box (a colour
per body) and ``twin.json``."""

import json
from pathlib import Path

import numpy as np
import torch
from sim_fixtures import kitchen

from drawer_lib.sim.mjcf import build_spec, write_mjcf
from drawer_lib.splat.gaussians import box_surface_gaussians, concat
from drawer_lib.splat.ply import write_gaussian_ply
from drawer_lib.splat.render import Gaussians
from drawer_lib.splat.sh import C0

BODY_COLORS = {"static": (0.7, 0.7, 0.7), "drawer_0": (0.9, 0.15, 0.1), "door_0": (0.1, 0.8, 0.2),
               "flap_0": (0.15, 0.3, 0.95), "cup_0": (0.9, 0.8, 0.1), "cup_1": (0.8, 0.2, 0.8)}


def _box_gaussians(shapes, color, spacing):
    gs = [box_surface_gaussians(s.box, np.asarray(color), spacing, sh_degree=0)
          for s in shapes if s.kind == "box"]
    return concat(gs) if gs else None


def write_tiny_twin(folder: Path, spacing: float = 0.03) -> Path:
    """Write the twin into ``folder`` (created) and return it."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    model = kitchen()
    write_mjcf(build_spec(model), folder)
    (folder / "gaussians").mkdir(exist_ok=True)
    write_gaussian_ply(folder / "gaussians" / "static.ply", _box_gaussians(model.static_collision, BODY_COLORS["static"], 0.1))
    parts = []
    for b in [*model.parts, *model.rigid]:
        g = _box_gaussians(b.collision, BODY_COLORS[b.id], spacing)
        if g is None:  # a cup: Gaussians on its mesh's vertices
            v = torch.as_tensor(np.concatenate([s.vertices for s in b.visual]), dtype=torch.float32)
            n = len(v)
            g = Gaussians(v, torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1), torch.full((n, 3), 0.01), torch.full((n,), 0.9),
                          ((torch.tensor(BODY_COLORS[b.id]) - 0.5) / C0).view(1, 1, 3).repeat(n, 1, 1))
        write_gaussian_ply(folder / "gaussians" / f"{b.id}.ply", g)
        kind = getattr(b, "kind", "rigid")
        parts.append({"id": b.id, "kind": kind, "body": b.id, "joint": b.id,
                      "actuator": b.id if kind != "rigid" else None, "gaussians": f"gaussians/{b.id}.ply",
                      "collision": [], "interior": {}})
    (folder / "twin.json").write_text(json.dumps({"schema": "drawer.twin/1", "parts": parts, "static": {
        "body": "static", "gaussians": "gaussians/static.ply", "collision": []}}, indent=1))
    return folder
