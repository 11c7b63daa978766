"""``sdf/field.pt``: a neural field or a dense SDF grid (the TSDF baseline), and loading either as
an SDF function for the mesh stage."""

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

from drawer_lib.config.typed import to_tree, to_typed
from drawer_lib.errors import InputError
from drawer_lib.sdf.config import NeuralConfig
from drawer_lib.sdf.field import SDFField

FORMAT = "drawer.sdf/1"


@dataclass
class GridSDF:
    """SDF samples on a regular grid (vertex k at lo + k * cell); NaN = never observed.
    ``sdf(x)`` interpolates trilinearly and returns ``unknown`` where any corner is unobserved."""

    lo: np.ndarray  # [3]
    cell: float
    values: np.ndarray  # [X, Y, Z] float32
    unknown: float = 1.0

    @property
    def hi(self) -> np.ndarray:
        return self.lo + self.cell * (np.array(self.values.shape) - 1)

    def observed(self) -> np.ndarray:
        return np.isfinite(self.values)

    @torch.no_grad()
    def sdf(self, x: Tensor) -> Tensor:
        v = torch.tensor(self.values, dtype=torch.float32).permute(2, 1, 0)[None, None]
        known = torch.isfinite(v)
        vals = torch.where(known, v, torch.zeros_like(v))
        ext = torch.tensor(self.hi - self.lo, dtype=torch.float32)
        g = (((x - torch.tensor(self.lo, dtype=torch.float32)) / ext) * 2 - 1)[None, :, None, None, :]
        s = F.grid_sample(vals, g, align_corners=True, padding_mode="border").reshape(-1)
        k = F.grid_sample(known.float(), g, align_corners=True, padding_mode="border").reshape(-1)
        inside = ((g.reshape(-1, 3).abs() <= 1).all(-1))
        return torch.where((k > 0.999) & inside, s, torch.full_like(s, self.unknown))


def save_neural(path: Path, field: SDFField, cfg: NeuralConfig, info: dict) -> None:
    torch.save({"format": FORMAT, "kind": "neural", "config": to_tree(cfg), "state": field.state_dict(),
                "box": [field.enc.lo.tolist(), field.enc.hi.tolist()], "center": field.center.tolist(),
                "radius": field.radius, "info": info}, path)


def save_grid(path: Path, grid: GridSDF, info: dict) -> None:
    torch.save({"format": FORMAT, "kind": "grid", "lo": grid.lo.tolist(), "cell": grid.cell,
                "values": torch.from_numpy(grid.values.astype(np.float32)), "unknown": grid.unknown, "info": info}, path)


@dataclass
class LoadedField:
    """What the mesh stage needs: an SDF function, the box it is defined on, how it was made."""

    kind: str
    sdf: object  # callable [N, 3] -> [N]
    lo: np.ndarray
    hi: np.ndarray
    info: dict
    grid: GridSDF | None = None
    field: SDFField | None = None


def _with_defaults(default: dict, saved: dict) -> dict:
    """``saved`` over ``default``, recursively: keys a later version of the config added take
    their default, so fields saved by earlier versions still load (unknown keys still fail)."""
    out = dict(default)
    for k, v in saved.items():
        out[k] = _with_defaults(default[k], v) if isinstance(v, dict) and isinstance(default.get(k), dict) else v
    return out


def load_field(path: Path) -> LoadedField:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: SDF field file is missing (run the sdf stage first)")
    try:
        d = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as e:  # torch raises many kinds for corrupt files
        raise InputError(f"{path}: unreadable SDF field ({type(e).__name__}: {e})") from e
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise InputError(f"{path}: not a {FORMAT} file")
    if d["kind"] == "grid":
        g = GridSDF(np.asarray(d["lo"], np.float64), float(d["cell"]), d["values"].numpy(), float(d["unknown"]))
        return LoadedField("grid", g.sdf, g.lo, g.hi, d["info"], grid=g)
    from drawer_lib.sdf.train import build_field

    conf = _with_defaults(dataclasses.asdict(NeuralConfig()), d["config"])
    if np.asarray(d["center"]).ndim == 1 and "init" not in d["config"].get("network", {}):
        conf["network"]["init"] = "sphere"  # saved before the capsule init existed
    cfg = to_typed(NeuralConfig, conf, f"{path}:config")
    lo, hi = (np.asarray(b, np.float64) for b in d["box"])
    f = build_field(cfg, lo, hi, np.asarray(d["center"]), float(d["radius"]))
    state = dict(d["state"])
    if state["center"].dim() == 1:  # fields saved before the capsule init: a sphere
        state["center"] = state["center"].expand(2, 3).clone()
    f.load_state_dict(state)
    f.eval()
    return LoadedField("neural", f.sdf, lo, hi, d["info"], field=f)
