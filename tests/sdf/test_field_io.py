"""A neural field saved by an earlier version of the config (before ``network.init`` and the
depth-point keys existed, a sphere init with a 1-D centre) still loads, and gives the same SDF."""

import numpy as np
import torch

from drawer_lib.sdf.config import NeuralConfig
from drawer_lib.sdf.io import load_field, save_neural
from drawer_lib.sdf.train import build_field


def test_a_field_saved_before_the_capsule_init_and_depth_points_loads(tmp_path):
    cfg = NeuralConfig()
    lo, hi = np.array([-1.0, -1.0, -0.5]), np.array([1.0, 1.0, 1.5])
    field = build_field(cfg, lo, hi, np.array([[0.1, 0.0, 0.8]] * 2), 1.2)  # a sphere: both ends equal
    with torch.no_grad():
        field.enc.table.normal_(0, 1e-2)
    save_neural(tmp_path / "new.pt", field, cfg, {"note": "x"})
    d = torch.load(tmp_path / "new.pt", weights_only=False)
    # what an earlier version wrote: no init / depth-point keys, the centre a point
    del d["config"]["network"]["init"]
    for k in ("depth_points", "depth_band", "depth_free", "depth_behind"):
        del d["config"]["sampling"][k]
    del d["config"]["losses"]["depth_points"]
    d["center"] = np.asarray(d["center"])[0].tolist()
    d["state"]["center"] = d["state"]["center"][0].clone()
    torch.save(d, tmp_path / "old.pt")
    x = torch.rand(100, 3) * 2 - 1
    old, new = load_field(tmp_path / "old.pt"), load_field(tmp_path / "new.pt")
    torch.testing.assert_close(old.sdf(x), new.sdf(x))
    assert old.field.center.shape == (2, 3)
