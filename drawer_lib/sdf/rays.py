"""Training rays of a capture: per-pixel targets of the train frames and batch sampling.

Rays are parametrised so that their camera-frame z component is 1: the parameter t of a point
o + t d is its z-depth, so rendered depths compare directly with depth maps.
"""

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from drawer_lib.errors import InputError
from drawer_lib.geometry.camera import pixel_dirs
from drawer_lib.io.capture import Capture
from drawer_lib.sdf.priors import MonoEstimator


def _stack(frames: list[int], read, dtype: torch.dtype) -> Tensor:
    """[N, ...] of ``read(i)`` for each frame, filled one frame at a time (no list of copies)."""
    first = torch.as_tensor(read(frames[0]))
    out = torch.empty((len(frames), *first.shape), dtype=dtype)
    out[0] = first
    for k, i in enumerate(frames[1:], 1):
        out[k] = torch.as_tensor(read(i))
    return out


@dataclass
class RayBatch:
    origins: Tensor  # [R, 3]
    dirs: Tensor  # [R, 3] (camera z component 1)
    rgb: Tensor  # [R, 3] in [0, 1]
    depth: Tensor | None  # [R] metric z-depth, 0 = invalid
    mono_depth: Tensor | None  # [R]
    normal: Tensor | None  # [R, 3] world frame
    groups: int  # rays come in `groups` consecutive blocks, each from one image


class RayBank:
    """Targets of the train frames, held in memory (colour as uint8, the rest float32), sampled
    in image groups. Each frame is read and flattened on its own."""

    def __init__(self, cap: Capture, frames: list[int], use_depth: bool, mono: MonoEstimator | None,
                 use_mono_depth: bool, use_normal: bool, sparse_points: np.ndarray | None = None):
        self.intr = cap.intrinsics
        if cap.intrinsics.has_distortion:
            raise InputError(f"{cap.root}: the SDF needs undistorted (PINHOLE) images; this capture has distortion "
                             f"{cap.intrinsics.dist}")
        self.frames = frames
        c2w = np.stack([cap.frames[i].c2w for i in frames])
        self.R = torch.tensor(c2w[:, :3, :3], dtype=torch.float32)
        self.C = torch.tensor(c2w[:, :3, 3], dtype=torch.float32)
        self.d_cam = torch.tensor(pixel_dirs(self.intr).reshape(-1, 3), dtype=torch.float32)  # [H*W, 3], z = 1
        n_pix = self.intr.width * self.intr.height
        self.rgb_u8 = _stack(frames, lambda i: cap.image(i).reshape(n_pix, 3), torch.uint8)  # [N, H*W, 3]
        self.depth = self.mono = self.normal = None
        if use_depth:
            self.depth = _stack(frames, lambda i: cap.depth(i).reshape(n_pix), torch.float32)
        if use_mono_depth:
            self.mono = _stack(frames, lambda i: mono.depth(i).reshape(n_pix), torch.float32)
        if use_normal:  # camera -> world frame, frame by frame
            self.normal = _stack(frames, lambda i: mono.normal(i).reshape(n_pix, 3), torch.float32)
            for k in range(len(frames)):
                self.normal[k] = torch.einsum("ab,nb->na", self.R[k], self.normal[k])
        self.sfm = None
        if sparse_points is not None and len(sparse_points):
            self.sfm = self._project(sparse_points)

    @property
    def n_images(self) -> int:
        return len(self.frames)

    @property
    def n_pixels(self) -> int:
        return self.intr.width * self.intr.height

    def _project(self, X: np.ndarray) -> tuple[Tensor, Tensor, Tensor] | None:
        """(image index, pixel index, z-depth) of points seen by each train frame (in front,
        inside the image); visibility is not tested (SfM points were triangulated from views)."""
        imgs, pixs, zs = [], [], []
        Xt = torch.tensor(X, dtype=torch.float32)
        for k in range(self.n_images):
            pc = (Xt - self.C[k]) @ self.R[k]
            z = pc[:, 2]
            u = self.intr.fx * pc[:, 0] / z.clamp_min(1e-6) + self.intr.cx
            v = self.intr.fy * pc[:, 1] / z.clamp_min(1e-6) + self.intr.cy
            ok = (z > 0.05) & (u >= 0) & (u < self.intr.width) & (v >= 0) & (v < self.intr.height)
            pix = v[ok].long() * self.intr.width + u[ok].long()
            imgs.append(torch.full_like(pix, k))
            pixs.append(pix)
            zs.append(z[ok])
        if not sum(len(p) for p in pixs):
            return None
        return torch.cat(imgs), torch.cat(pixs), torch.cat(zs)

    def rays(self, img: Tensor, pix: Tensor) -> tuple[Tensor, Tensor]:
        """Origins and directions [N, 3] of pixels ``pix`` of train images ``img`` (both [N])."""
        d = torch.einsum("nab,nb->na", self.R[img], self.d_cam[pix])
        return self.C[img], d

    def sample(self, groups: int, per_group: int, gen: torch.Generator) -> RayBatch:
        img = torch.randint(0, self.n_images, (groups,), generator=gen).repeat_interleave(per_group)
        pix = torch.randint(0, self.n_pixels, (groups * per_group,), generator=gen)
        o, d = self.rays(img, pix)
        return RayBatch(
            o, d, self.rgb_u8[img, pix].float() / 255.0,
            None if self.depth is None else self.depth[img, pix],
            None if self.mono is None else self.mono[img, pix],
            None if self.normal is None else self.normal[img, pix],
            groups,
        )

    @property
    def rgb(self) -> Tensor:
        """[N, H * W, 3] float32 colours in [0, 1] of all train pixels (a copy: 4x the bank's)."""
        return self.rgb_u8.float() / 255.0

    def sample_depth(self, n: int, gen: torch.Generator) -> tuple[Tensor, Tensor, Tensor]:
        """Origins, directions [M, 3] and metric z-depths [M] of ``n`` pixels drawn uniformly over
        all train pixels, keeping the M <= n with a valid (> 0) depth (needs ``self.depth``)."""
        if self.depth is None:
            raise ValueError("RayBank.sample_depth: the bank has no metric depth")
        img = torch.randint(0, self.n_images, (n,), generator=gen)
        pix = torch.randint(0, self.n_pixels, (n,), generator=gen)
        z = self.depth[img, pix]
        ok = z > 0
        img, pix, z = img[ok], pix[ok], z[ok]
        o, d = self.rays(img, pix)
        return o, d, z

    def sample_sfm(self, n: int, gen: torch.Generator) -> tuple[Tensor, Tensor, Tensor] | None:
        """Rays through the pixels of ``n`` random SfM observations, with their depths."""
        if self.sfm is None:
            return None
        img, pix, z = self.sfm
        k = torch.randint(0, len(z), (n,), generator=gen)
        o, d = self.rays(img[k], pix[k])
        return o, d, z[k]


def focus_depth(C: np.ndarray, D: np.ndarray) -> float:
    """Median depth, along each optical axis, of the point closest to all optical axes (least
    squares): the typical viewing depth of a capture without depth. C, D: [N, 3] centres and unit
    viewing directions. NaN or <= 0 when the axes do not meet in front of the cameras."""
    A, b = np.zeros((3, 3)), np.zeros(3)
    for c, d in zip(C, D):
        Pm = np.eye(3) - np.outer(d, d)
        A, b = A + Pm, b + Pm @ c
    focus = np.linalg.lstsq(A, b, rcond=None)[0]
    return float(np.median([(focus - c) @ d for c, d in zip(C, D)]))


def scene_box(cap: Capture, bank: RayBank, margin: float, far_factor: float,
              sparse_points: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, float, str]:
    """(lo, hi, typical viewing depth, how) of the reconstruction box; see BoundsConfig.
    Depth or SfM points give the 0.05-99.95 % range of the points plus the margin (the
    percentiles drop outliers only: a side wall seen at the edge of a few frames must stay in)."""
    C = bank.C.numpy()
    if bank.depth is not None:
        pts, zs = [], []
        sub = torch.arange(0, bank.n_pixels, 7)
        for k in range(bank.n_images):
            z = bank.depth[k, sub]
            ok = z > 0
            o, d = bank.rays(torch.full((int(ok.sum()),), k), sub[ok])
            pts.append((o + d * z[ok, None]).numpy())
            zs.append(z[ok].numpy())
        P, typical, how = np.concatenate(pts), float(np.median(np.concatenate(zs))), "metric depth"
    elif sparse_points is not None and len(sparse_points) >= 10:
        P = sparse_points
        typical = float(np.median(np.linalg.norm(P[:, None] - C[None], axis=-1)))
        how = "SfM points"
    else:
        typical = focus_depth(C, bank.R[:, :, 2].numpy())
        if not np.isfinite(typical) or typical <= 0:
            raise InputError(f"{cap.root}: the cameras' optical axes do not meet in front of them; "
                             "the scene box cannot be found without depth or SfM points")
        far = far_factor * typical
        corners = np.array([[0, 0], [bank.intr.width, 0], [0, bank.intr.height], [bank.intr.width, bank.intr.height]])
        dc = np.stack([(corners[:, 0] - bank.intr.cx) / bank.intr.fx, (corners[:, 1] - bank.intr.cy) / bank.intr.fy,
                       np.ones(4)], -1)
        P = np.concatenate([C] + [c + far * dc @ R.T for c, R in zip(C, bank.R.numpy())])
        how = f"camera frusta cut at {far_factor} x the {typical:.2f} m focus depth"
        return P.min(0) - margin, P.max(0) + margin, typical, how
    lo, hi = np.percentile(P, 0.05, axis=0) - margin, np.percentile(P, 99.95, axis=0) + margin
    return lo, hi, typical, how
