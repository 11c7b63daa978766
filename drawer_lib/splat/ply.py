"""3D Gaussian splatting PLY (the INRIA layout that common Gaussian viewers read): write and read
activated Gaussians, and the face binding of mesh-anchored Gaussians.

Vertex properties, float32, in this order: x y z, nx ny nz (zeros), f_dc_0..2, f_rest_0..(3(K-1)-1)
(channel-major: all of R's higher-order coefficients, then G's, then B's), opacity (logit),
scale_0..2 (log), rot_0..3 (wxyz, normalised).
"""

from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from drawer_lib.errors import InputError, NonFiniteError
from drawer_lib.io.atomic import atomic_open
from drawer_lib.splat.render import Gaussians


def gaussian_ply_fields(k_rest: int) -> list[str]:
    return (["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
            + [f"f_rest_{i}" for i in range(3 * k_rest)] + ["opacity", "scale_0", "scale_1", "scale_2"]
            + [f"rot_{i}" for i in range(4)])


def write_gaussian_ply(path: Path, g: Gaussians) -> None:
    """Binary little-endian PLY of activated Gaussians (stored as logit / log / unit wxyz)."""
    n, K = g.sh.shape[0], g.sh.shape[1]
    with torch.no_grad():
        op = g.opacities.double().clamp(1e-7, 1 - 1e-7)
        cols = [g.means, torch.zeros(n, 3, dtype=g.means.dtype), g.sh[:, 0],
                g.sh[:, 1:].transpose(1, 2).reshape(n, -1), torch.log(op / (1 - op))[:, None],
                torch.log(g.scales.double().clamp_min(1e-30)), g.quats / g.quats.norm(dim=-1, keepdim=True)]
        data = torch.cat([c.double() for c in cols], 1).numpy().astype("<f4")
    if not np.all(np.isfinite(data)):
        raise NonFiniteError(f"{path}: refusing to write non-finite Gaussian parameters")
    names = gaussian_ply_fields(K - 1)
    header = "ply\nformat binary_little_endian 1.0\n" + f"element vertex {n}\n"
    header += "".join(f"property float {name}\n" for name in names) + "end_header\n"
    with atomic_open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(np.ascontiguousarray(data).tobytes())


def read_ply_columns(path: Path) -> dict[str, np.ndarray]:
    """The columns of a binary little-endian float PLY, by property name."""
    raw = Path(path).read_bytes()
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    lines = raw[:end].decode("ascii").splitlines()
    if lines[1] != "format binary_little_endian 1.0":
        raise InputError(f"{path}: not a binary little-endian PLY")
    n = int(next(x for x in lines if x.startswith("element vertex")).split()[-1])
    names = [x.split()[-1] for x in lines if x.startswith("property float")]
    arr = np.frombuffer(raw[end:], "<f4", count=n * len(names)).reshape(n, len(names))
    return {k: arr[:, i] for i, k in enumerate(names)}


def read_gaussian_ply(path: Path) -> Gaussians:
    """The activated Gaussians of an INRIA-layout PLY (:func:`write_gaussian_ply`)."""
    c = read_ply_columns(path)
    need = {"x", "y", "z", "f_dc_0", "opacity", "scale_0", "rot_0"}
    if not need <= set(c):
        raise InputError(f"{path}: not a Gaussian PLY (missing {sorted(need - set(c))})")
    n = len(c["x"])
    k_rest = sum(k.startswith("f_rest_") for k in c) // 3
    t = lambda *ks: torch.from_numpy(np.stack([c[k] for k in ks], -1).astype(np.float32))  # noqa: E731
    rest = (t(*[f"f_rest_{i}" for i in range(3 * k_rest)]).view(n, 3, k_rest).transpose(1, 2)
            if k_rest else torch.zeros(n, 0, 3))
    sh = torch.cat([t("f_dc_0", "f_dc_1", "f_dc_2")[:, None], rest], 1)
    return Gaussians(t("x", "y", "z"), t("rot_0", "rot_1", "rot_2", "rot_3"), torch.exp(t("scale_0", "scale_1", "scale_2")),
                     torch.sigmoid(torch.from_numpy(c["opacity"].astype(np.float32))), sh)


def write_face_binding(path: Path, face_of_gaussian: Tensor, face_ids: Tensor, means_2d: Tensor, elevate: Tensor) -> None:
    """``binding.npz``: for Gaussian i (PLY row i) the mesh face it lives on
    (``mesh_face[i]``), its in-face 2D position and normal offset — what moving a part's
    Gaussians with its faces needs."""
    np.savez(Path(path), mesh_face=face_ids[face_of_gaussian].numpy().astype(np.int64),
             means_2d=means_2d.detach().numpy().astype(np.float32), elevate=elevate.detach().numpy().astype(np.float32))
