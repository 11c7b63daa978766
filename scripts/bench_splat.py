#!/usr/bin/env python
"""Benchmark of the CPU Gaussian rasterizer: forward+backward time at 128x96 and 256x192 with 5k
and 20k Gaussians, side by side in one run with gsplat's pure-PyTorch reference path.

gsplat 1.5.3 installs on CPU torch (`pip install gsplat==1.5.3`, not a project dependency).
Its `gsplat/cuda/_torch_impl.py` projection and SH run on the CPU; its pixel stage
(`_rasterize_to_pixels`) needs a CUDA helper (`rasterize_to_indices_in_range`) and nerfacc's
CUDA-only packed cumprod, and its `_isect_tiles` is a Python loop per Gaussian. This script
replaces those three with short pure-PyTorch shims (vectorised over the Gaussians of a tile;
same termination rule) and times projection + SH + compositing, forward and backward.

Ours and the reference run in two worker processes, alternately: ``--repeat`` rounds after one
warm-up round; in a round each is called three times in a row (warm, as in a training loop) and
its median call kept. The speed-up is the median of the rounds' own ratios (with their range), so
that the machine's load, which drifts over seconds, hits both sides of each ratio alike. Only one
worker computes at a time (the other waits on its pipe).

Two processes, because each side gets its own OpenMP wait policy, as it runs for its users:
ours imports drawer_lib first, which makes torch's OpenMP workers wait passively (see
``drawer_lib/__init__.py``: spinning workers take the cores from the numba kernels); the
reference is pure torch, with libgomp's default (spin, then sleep), which suits its hundreds of
small torch ops better (``--ref-wait-policy PASSIVE`` measures it the other way).

    python scripts/bench_splat.py [--repeat 7] [--sizes 128x96 256x192] [--counts 5000 20000]
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
import types
from pathlib import Path
from types import SimpleNamespace

import numpy as np

if os.environ.get("BENCH_SPLAT_WORKER") == "ours":
    import drawer_lib  # noqa: F401  (before torch: the library's OpenMP wait policy, as the pipeline runs)
import torch  # noqa: E402

SH_DEGREE = 3


def scene(n: int, seed: int = 0) -> list[torch.Tensor]:
    """Gaussians filling the view frustum at 2-5 m, sizes 5 mm - 5 cm, random orientation."""
    g = torch.Generator().manual_seed(seed)
    z = torch.rand(n, generator=g) * 3 + 2
    x = (torch.rand(n, generator=g) * 2 - 1) * z * 0.6
    y = (torch.rand(n, generator=g) * 2 - 1) * z * 0.45
    means = torch.stack([x, y, z], -1)
    quats = torch.randn(n, 4, generator=g)
    scales = torch.exp(torch.rand(n, 3, generator=g) * math.log(10) + math.log(0.005))
    opac = torch.rand(n, generator=g) * 0.8 + 0.1
    sh = torch.randn(n, 16, 3, generator=g) * 0.2
    return [means, quats, scales, opac, sh]


# --- pure-PyTorch shims for gsplat's CUDA-only pieces ------------------------------------------

def _render_weight_from_alpha(alphas, ray_indices, n_rays):
    """nerfacc's packed exclusive cumprod: weights = alpha * prod_{earlier on the ray} (1 - alpha)."""
    log1m = torch.log1p(-alphas.double())  # float64: the running sum spans every ray of the image
    cs = torch.cumsum(log1m, 0)
    start = torch.ones_like(ray_indices, dtype=torch.bool)
    start[1:] = ray_indices[1:] != ray_indices[:-1]
    seg = torch.cumsum(start.long(), 0) - 1
    base = (cs - log1m)[start]  # cumulative sum before each segment
    trans = torch.exp(cs - log1m - base[seg]).to(alphas.dtype)
    return alphas * trans, trans


def _accumulate_along_rays(weights, values, ray_indices, n_rays):
    v = weights[:, None] if values is None else weights[:, None] * values
    return torch.zeros(n_rays, v.shape[1], dtype=v.dtype).index_add(0, ray_indices, v)


@torch.no_grad()
def _rasterize_to_indices_in_range(range_start, range_end, transmittances, means2d, conics, opacities, image_width,
                                   image_height, tile_size, isect_offsets, flatten_ids):
    """(gaussian ids, pixel ids, image ids) of the contributions of list batches
    [range_start, range_end) of every tile (one image), ordered by pixel then depth."""
    N = means2d.shape[-2]
    m, co, op = means2d.reshape(-1, 2), conics.reshape(-1, 3), opacities.reshape(-1)
    offs = torch.cat([isect_offsets.flatten(), torch.tensor([len(flatten_ids)])]).tolist()
    th, tw = isect_offsets.shape[-2:]
    block = tile_size * tile_size
    out_g, out_p = [], []
    for t in range(th * tw):
        a = offs[t] + range_start * block
        b = min(offs[t] + range_end * block, offs[t + 1])
        if a >= b:
            continue
        gid = flatten_ids[a:b].long() % N
        ty, tx = divmod(t, tw)
        ys = torch.arange(ty * tile_size, min((ty + 1) * tile_size, image_height))
        xs = torch.arange(tx * tile_size, min((tx + 1) * tile_size, image_width))
        py, px = torch.meshgrid(ys, xs, indexing="ij")
        pix = (py * image_width + px).reshape(-1)
        d = torch.stack([px.reshape(-1) + 0.5, py.reshape(-1) + 0.5], -1)[:, None] - m[gid][None]  # [P, G, 2]
        c = co[gid][None]
        sig = 0.5 * (c[..., 0] * d[..., 0] ** 2 + c[..., 2] * d[..., 1] ** 2) + c[..., 1] * d[..., 0] * d[..., 1]
        alpha = torch.clamp_max(op[gid][None] * torch.exp(-sig), 0.999)
        ok = (sig >= 0) & (alpha >= 1.0 / 255.0)
        T = transmittances.reshape(-1)[pix][:, None] * torch.cumprod(1 - alpha * ok, 1)
        keep = ok & (T > 1e-4)
        pi, gi = torch.nonzero(keep, as_tuple=True)
        out_g.append(gid[gi])
        out_p.append(pix[pi])
    if not out_g:
        e = torch.zeros(0, dtype=torch.long)
        return e, e, e
    g, p = torch.cat(out_g), torch.cat(out_p)
    return g, p, torch.zeros_like(g)


def _isect_tiles(means2d, radii, depths, tile_size, tile_width, tile_height):
    """Vectorised replacement of gsplat's per-Gaussian Python loop: (flatten ids, offsets)."""
    m, r = means2d[0], radii[0].float()
    lo = torch.floor((m - r) / tile_size).clamp_min(0).long()
    hi = torch.ceil((m + r) / tile_size).long()
    hi[:, 0] = hi[:, 0].clamp(max=tile_width)
    hi[:, 1] = hi[:, 1].clamp(max=tile_height)
    vis = (radii[0] > 0).all(-1) & (hi > lo).all(-1)
    ids = torch.nonzero(vis)[:, 0]
    order = ids[torch.argsort(depths[0, ids], stable=True)]
    tiles, gs = [], []
    for y in range(tile_height):
        for x in range(tile_width):
            sel = order[(lo[order, 0] <= x) & (hi[order, 0] > x) & (lo[order, 1] <= y) & (hi[order, 1] > y)]
            tiles.append(len(sel))
            gs.append(sel)
    counts = torch.tensor(tiles)
    offsets = (torch.cumsum(counts, 0) - counts).reshape(1, tile_height, tile_width).int()
    return torch.cat(gs).int(), offsets


def gsplat_reference(params, cam, tile: int = 16):
    import gsplat.cuda._torch_impl as T
    import gsplat.cuda._wrapper as Wr

    if "nerfacc" not in sys.modules:  # the CPU shim of nerfacc's two packed ops
        mod = types.ModuleType("nerfacc")
        mod.render_weight_from_alpha = _render_weight_from_alpha
        mod.accumulate_along_rays = _accumulate_along_rays
        sys.modules["nerfacc"] = mod
    Wr.rasterize_to_indices_in_range = _rasterize_to_indices_in_range
    means, quats, scales, opac, sh = params
    fx, fy, cx, cy = cam.intrinsics.params
    Ks = torch.tensor([[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]], dtype=means.dtype)
    viewmat = torch.as_tensor(cam.w2c, dtype=means.dtype)
    covars, _ = T._quat_scale_to_covar_preci(quats, scales, compute_covar=True, compute_preci=False, triu=False)
    radii, means2d, depths, conics, _ = T._fully_fused_projection(means, covars, viewmat[None], Ks, cam.width,
                                                                  cam.height, eps2d=0.3)
    dirs = means[None] - torch.as_tensor(cam.center, dtype=means.dtype)[None, None]
    colors = torch.clamp_min(T._spherical_harmonics(SH_DEGREE, dirs, sh[None]) + 0.5, 0.0)
    tw, th = math.ceil(cam.width / tile), math.ceil(cam.height / tile)
    flat, offsets = _isect_tiles(means2d.detach(), radii, depths.detach(), tile, tw, th)
    rgb, alpha = T._rasterize_to_pixels(means2d, conics, colors, opac[None].expand(1, -1), cam.width, cam.height, tile,
                                        offsets, flat)
    return rgb[0], alpha[0, ..., 0]


def camera(W: int, H: int) -> SimpleNamespace:
    """The benchmark's pinhole camera at the origin looking down +z (f = 0.8 W): what the
    reference reads of one (``params``, ``w2c``, ``center``, ``width``, ``height``)."""
    f = 0.8 * W
    return SimpleNamespace(intrinsics=SimpleNamespace(params=(f, f, W / 2, H / 2)), w2c=np.eye(4),
                           center=np.zeros(3), width=W, height=H)


def _finish(rgb, alpha, params, backward: bool):
    """The benchmark's loss on one side's render (sum of RGB and alpha), backpropagated when
    ``backward`` after the gradients are set to None, as a training step's
    ``optimizer.zero_grad(set_to_none=True)`` does; returns ``rgb``."""
    if backward:
        for t in params:
            t.grad = None
        (rgb.sum() + alpha.sum()).backward()
    return rgb


def worker(side: str) -> None:
    """One side of the benchmark, driven by JSON lines on stdin: {"setup": [W, H, N]} builds the
    scene; {"time": block, "backward": bool} answers with the seconds of ``block`` calls (forward
    alone: without autograd, as an evaluation render);
    {"image": path} saves the forward RGB [H, W, 3] there."""
    threads = int(os.environ.get("BENCH_SPLAT_THREADS", "0")) or os.cpu_count() or 1
    torch.set_num_threads(threads)
    fn = None
    for line in sys.stdin:
        cmd = json.loads(line)
        if "setup" in cmd:
            W, H, n = cmd["setup"]
            params = [t.clone().requires_grad_(True) for t in scene(n)]
            if side == "ours":
                import numba

                from drawer_lib.geometry.camera import Camera, Intrinsics
                from drawer_lib.splat.render import Gaussians, render

                numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
                cam = Camera(Intrinsics(0.8 * W, 0.8 * W, W / 2, H / 2, W, H), np.eye(4))

                def fn(backward=True, cam=cam, params=params):
                    out = render(Gaussians(*params), cam, SH_DEGREE)
                    return _finish(out.rgb, out.alpha, params, backward)
            else:
                cam = camera(W, H)

                def fn(backward=True, cam=cam, params=params):
                    return _finish(*gsplat_reference(params, cam), params, backward)
            reply = {"ok": True}
        elif "time" in cmd:
            ts = []
            backward = cmd.get("backward", True)
            for _ in range(cmd["time"]):
                t = time.perf_counter()
                with torch.set_grad_enabled(backward):  # a forward alone renders as evaluation does
                    fn(backward)
                ts.append(time.perf_counter() - t)
            reply = {"s": ts}
        elif "image" in cmd:
            with torch.no_grad():
                np.save(cmd["image"], fn(False).detach().numpy())
            reply = {"ok": True}
        else:
            raise SystemExit(f"bench_splat worker: unknown command {cmd}")
        print(json.dumps(reply), flush=True)


class Worker:
    """A worker process of one side (``side``: ours / ref) with the environment ``env``."""

    def __init__(self, side: str, env: dict):
        self.p = subprocess.Popen([sys.executable, __file__], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                  env={**env, "BENCH_SPLAT_WORKER": side})

    def __call__(self, **cmd):
        self.p.stdin.write(json.dumps(cmd) + "\n")
        self.p.stdin.flush()
        line = self.p.stdout.readline()
        if not line:
            raise SystemExit(f"bench_splat: the worker exited with {self.p.wait()}")
        return json.loads(line)

    def close(self):
        self.p.stdin.close()
        self.p.wait()


def interleaved(calls: dict, rounds: int, block: int = 3, warmup: int = 1) -> dict[str, np.ndarray]:
    """Seconds per call of each entry of ``calls`` (name -> (worker, backward)), one value per
    round: each round has every entry's worker run ``block`` calls in a row (warm caches and
    buffers, as in a training loop) and keeps their median; ``warmup`` untimed rounds first."""
    ts = {k: [] for k in calls}
    for r in range(warmup + rounds):
        for k, (w, backward) in calls.items():
            block_ts = w(time=block, backward=backward)["s"]
            if r >= warmup:
                ts[k].append(float(np.median(block_ts)))
    return {k: np.asarray(v) for k, v in ts.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--sizes", nargs="+", default=["128x96", "256x192"])
    ap.add_argument("--counts", nargs="+", type=int, default=[5000, 20000])
    ap.add_argument("--threads", type=int, default=0, help="torch and numba threads per side (default: every core)")
    ap.add_argument("--ref-wait-policy", default="", help="OMP_WAIT_POLICY of the reference's process "
                    "(default: libgomp's own, unset)")
    ap.add_argument("--no-reference", action="store_true", help="skip gsplat's reference path")
    a = ap.parse_args()
    have_ref = not a.no_reference
    if have_ref and subprocess.run([sys.executable, "-c", "import gsplat"], capture_output=True).returncode != 0:
        have_ref = False
        print("gsplat not installed (pip install gsplat==1.5.3): reference column skipped")
    env = {**os.environ, "BENCH_SPLAT_THREADS": str(a.threads)}
    ours = Worker("ours", env)  # with this shell's OMP_WAIT_POLICY if it sets one, else drawer_lib's
    ref = None
    if have_ref:
        ref_env = {k: v for k, v in env.items() if k != "OMP_WAIT_POLICY"}
        if a.ref_wait_policy:
            ref_env["OMP_WAIT_POLICY"] = a.ref_wait_policy
        ref = Worker("ref", ref_env)
    print(f"{'size':>8} {'N':>6} | {'ours fwd':>9} {'ours f+b':>9} | {'gsplat-torch f+b':>16} | "
          f"{'speed-up (range)':>18} | {'max |rgb diff|':>14}")
    with tempfile.TemporaryDirectory() as tmp:
        for size in a.sizes:
            W, H = map(int, size.split("x"))
            for n in a.counts:
                calls = {"fwd": (ours, False), "fb": (ours, True)}
                for w in [ours] + ([ref] if ref else []):
                    w(setup=[W, H, n])
                if ref:
                    calls["ref"] = (ref, True)
                t = interleaved(calls, a.repeat)
                row = f"{size:>8} {n:>6} | {1000 * np.median(t['fwd']):8.1f}  {1000 * np.median(t['fb']):8.1f}  |"
                if ref:
                    ratio = t["ref"] / t["fb"]
                    imgs = []
                    for name, w in (("ours", ours), ("ref", ref)):
                        path = str(Path(tmp) / f"{name}.npy")
                        w(image=path)
                        imgs.append(np.load(path))
                    diff = float(np.abs(imgs[0] - imgs[1]).max())
                    row += (f" {1000 * np.median(t['ref']):15.1f}  | {np.median(ratio):5.1f}x ({ratio.min():.1f}-"
                            f"{ratio.max():.1f}) | {diff:14.2e}")
                print(row + "   (ms)", flush=True)
    for w in [ours] + ([ref] if ref else []):
        w.close()


if __name__ == "__main__":
    if os.environ.get("BENCH_SPLAT_WORKER"):
        worker(os.environ["BENCH_SPLAT_WORKER"])
    else:
        main()
