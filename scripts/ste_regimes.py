#!/usr/bin/env python
"""Where does the straight-through estimator matter? ``movable_gs`` (hard clip) against
``movable_gs_ste`` (the paper's method) and ``free_gs`` (unconstrained, the ceiling of any
bound handling), trained under different regimes:

- ``default``: the ablation's config (kitchen_small, neural mesh decimated to 30k faces,
  position learning rate 4.8e-3);
- ``pos_lr_<lr>``: other position learning rates (the STE lets a Gaussian that crossed its
  bound come back; the hard clip freezes it there, so the faster the positions move relative
  to their faces, the more the two differ); with ``official_lr`` and ``default`` they draw
  ``<out>/position_lr.png``;
- at the official code's position rate 1.6e-4 (the first study, where the bounds were made to
  bind harder): ``official_lr``; ``short``: 900 steps (no opacity reset; densification until
  the end); ``tight_bounds``: the official code's default bounds (offset ±0.15 R,
  scales ≤ 0.5 R) instead of its scripts' (±2 R, ≤ 2 R); ``no_densify``: one Gaussian per face,
  no split / duplicate / cull (nothing replaces a Gaussian frozen at a bound);
  ``displaced_1cm``: the anchor mesh moved along its normals by a smooth random field (1 cm rms,
  10 cm correlation length; ``drawer_lib.perturb``), a reconstruction's bumps; ``tsdf_anchor``:
  the TSDF mesh of the geometry comparison as anchor (needs
  ``dvc repro geometry@kitchen_small-tsdf``).

Each run trains and evaluates exactly as the ``appearance`` stage does (same functions, same
test views, PSNR / SSIM / LPIPS) and records the fraction of raw parameters at or beyond each
bound (``at_bound_*``). Runs go ``--jobs`` at a time with the cores split between them (the
schedule is by steps, so the images do not depend on the machine's speed; the printed training
times do). Writes ``<out>/results.jsonl`` (one row per run; ``--reuse`` skips rows already
there) and ``<out>/summary.md``.

    python scripts/ste_regimes.py                       # all regimes, seed 0 (~2 h on 2 cores)
    python scripts/ste_regimes.py --regimes default --seeds 1,2 --clips hard,ste
"""

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def lr_overrides(lr: str) -> list[str]:
    """Hydra overrides setting the initial position learning rate, decayed 100x as by default."""
    return [f"appearance.lr.position={lr}", f"appearance.lr.position_final={float(lr) / 100:g}"]


# The regimes of the first study ran at the official code's position learning rate (1.6e-4 per
# step); they pin it so their numbers reproduce whatever the stage's default becomes.
OFFICIAL_LR = lr_overrides("1.6e-4")
POS_LRS = ("1.2e-3", "1.6e-2")  # with official_lr (1.6e-4) and default (4.8e-3): the learning-rate sweep
REGIMES = {  # name -> (Hydra overrides, anchor mesh: "default" | "displaced" | "tsdf")
    "default": ([], "default"),
    "official_lr": (OFFICIAL_LR, "default"),
    "short": ([*OFFICIAL_LR, "appearance.steps=900"], "default"),
    "tight_bounds": ([*OFFICIAL_LR, "appearance.bounds.elevate_coef=0.15", "appearance.bounds.upper_scale=0.5"],
                     "default"),
    "no_densify": ([*OFFICIAL_LR, "appearance.strategy=null"], "default"),
    "displaced_1cm": (OFFICIAL_LR, "displaced"),
    "tsdf_anchor": (OFFICIAL_LR, "tsdf"),
    **{f"pos_lr_{lr}": (lr_overrides(lr), "default") for lr in POS_LRS},
}
CLIPS = {"hard": "movable_gs", "ste": "movable_gs_ste", "free": "free_gs"}
DISPLACEMENT = {"rms_m": 0.01, "wavelength_m": 0.1, "seed": 0}


def run_one(scene: str, regime: str, clip: str, seed: int) -> dict:
    import torch
    import trimesh
    from hydra import compose, initialize_config_dir

    from drawer_lib.config.typed import to_typed
    from drawer_lib.io.capture import load_capture
    from drawer_lib.paths import ScenePaths
    from drawer_lib.perturb import displace_along_normals
    from drawer_lib.splat.anchored import bound_activity
    from drawer_lib.splat.config import AppearanceConfig
    from drawer_lib.splat.train import bounds_report, evaluate_images, prepare, render_test, train_gaussians

    overrides, anchor = REGIMES[regime]
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"scene={scene}", f"appearance_variant={CLIPS[clip]}",
                                                       f"seed={seed}", *overrides])
    app = to_typed(AppearanceConfig, cfg.appearance, "appearance")
    sp = ScenePaths(ROOT / cfg.paths.out, scene, "tsdf" if anchor == "tsdf" else None)
    cap = load_capture(sp.capture)
    mesh_path = sp.mesh
    if not mesh_path.is_file():
        raise SystemExit(f"error: {mesh_path} is missing (dvc repro the {'geometry' if anchor == 'tsdf' else 'mesh'} "
                         f"stage of {scene} first)")
    mesh = trimesh.load(mesh_path, process=False)
    extra = {}
    if anchor == "displaced":
        mesh, d = displace_along_normals(mesh, **DISPLACEMENT)
        extra["displacement_rms_m"] = float((d ** 2).mean() ** 0.5)
    sc = prepare(cap, mesh, app)
    st = train_gaussians(cap, sc, app, seed)
    res = evaluate_images(render_test(st.params, st.frames, app, sc), sc.test_rgb)
    violation = bounds_report(st.params, st.frames, app) if clip != "free" else None
    if violation is not None:
        raise AssertionError(f"{regime}/{clip}: {violation}")
    extra.update({f"at_bound_{k}": round(v, 4) for k, v in bound_activity(st.params, st.frames, app.bounds).items()})
    return {"scene": scene, "regime": regime, "clip": clip, "seed": seed, "psnr": res.psnr, "ssim": res.ssim,
            "lpips": res.lpips, "n_gaussians": int(st.params.face.shape[0]), "steps": st.steps,
            "train_s": round(st.train_s, 1), "threads": torch.get_num_threads(), **extra}


def summary(rows: list[dict]) -> str:
    lines = ["| regime | seed | hard clip PSNR / SSIM / LPIPS | STE PSNR / SSIM / LPIPS | free 3DGS PSNR / SSIM / LPIPS "
             "| STE − hard | free − hard (headroom) |", "|---|---|---|---|---|---|---|"]

    def fmt(r: dict | None) -> str:
        return f"{r['psnr']:.2f} / {r['ssim']:.4f} / {r['lpips']:.4f}" if r else "–"

    def diff(a: dict | None, b: dict | None) -> str:
        return f"{a['psnr'] - b['psnr']:+.2f} dB" if a and b else "–"

    for regime in REGIMES:
        for seed in sorted({r["seed"] for r in rows if r["regime"] == regime}):
            by = {r["clip"]: r for r in rows if r["regime"] == regime and r["seed"] == seed}
            h, s, f = by.get("hard"), by.get("ste"), by.get("free")
            lines.append(f"| {regime} | {seed} | {fmt(h)} | {fmt(s)} | {fmt(f)} | {diff(s, h)} | {diff(f, h)} |")
    return "\n".join(lines) + "\n"


def lr_of(regime: str) -> float | None:
    """The initial position learning rate of a regime that changes nothing else (else None)."""
    overrides, anchor = REGIMES[regime]
    if anchor != "default" or any(not o.startswith("appearance.lr.position") for o in overrides):
        return None
    given = [o.split("=")[1] for o in overrides if o.startswith("appearance.lr.position=")]
    if given:
        return float(given[0])
    from omegaconf import OmegaConf
    return float(OmegaConf.load(ROOT / "conf/appearance/default.yaml").lr.position)


def plot_lr(rows: list[dict], path: Path, seed: int = 0) -> bool:
    """Test PSNR of one seed against the position learning rate, one line per clip mode; False
    (nothing written) when no clip mode has two rates."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lrs = {g: lr_of(g) for g in REGIMES}
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    drawn = False
    for clip, colour in (("hard", "tab:red"), ("ste", "tab:blue"), ("free", "tab:gray")):
        pts: dict[float, list[float]] = {}
        for r in rows:
            lr = lrs.get(r["regime"])
            if r["clip"] == clip and r["seed"] == seed and lr is not None:
                pts.setdefault(lr, []).append(r["psnr"])
        if len(pts) < 2:
            continue
        x = sorted(pts)
        ax.plot(x, [sum(pts[v]) / len(pts[v]) for v in x], "o-", color=colour, label=f"{CLIPS[clip]} ({clip})")
        drawn = True
    if not drawn:
        plt.close(fig)
        return False
    ax.axvline(lrs["default"], color="k", ls=":", lw=1, label="default")
    ax.axvline(lrs["official_lr"], color="k", ls="--", lw=1, label="official code")
    ax.set_xscale("log")
    ax.set_xlabel("position learning rate (m / step, decayed 100x over the schedule)")
    ax.set_ylabel(f"test PSNR (dB), seed {seed}")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return True


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="kitchen_small")
    ap.add_argument("--regimes", default=",".join(REGIMES))
    ap.add_argument("--clips", default="hard,ste,free")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("/tmp/ste_regimes"))
    ap.add_argument("--reuse", action="store_true", help="skip runs already in <out>/results.jsonl")
    ap.add_argument("--one", nargs=4, metavar=("SCENE", "REGIME", "CLIP", "SEED"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one:
        print(json.dumps(run_one(a.one[0], a.one[1], a.one[2], int(a.one[3]))))
        return
    regimes, clips = a.regimes.split(","), a.clips.split(",")
    for name, given, known in (("regime", regimes, REGIMES), ("clip", clips, CLIPS)):
        bad = [x for x in given if x not in known]
        if bad:
            raise SystemExit(f"error: unknown {name} {bad}; choose from {list(known)}")
    seeds = [int(s) for s in a.seeds.split(",")]
    a.out.mkdir(parents=True, exist_ok=True)
    res_file = a.out / "results.jsonl"
    rows = [json.loads(line) for line in res_file.read_text().splitlines()] if a.reuse and res_file.is_file() else []
    if not a.reuse:
        res_file.write_text("")
    done = {(r["scene"], r["regime"], r["clip"], r["seed"]) for r in rows}
    todo = [(a.scene, g, c, s) for g in regimes for s in seeds for c in clips if (a.scene, g, c, s) not in done]
    threads = max(1, (os.cpu_count() or 2) // max(a.jobs, 1))
    env = {**os.environ, **{k: str(threads) for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")}}
    running: list[tuple[tuple, subprocess.Popen, float]] = []
    print(f"{len(todo)} runs, {a.jobs} at a time, {threads} thread(s) each")
    while todo or running:
        while todo and len(running) < a.jobs:
            job = todo.pop(0)
            cmd = [sys.executable, __file__, "--one", job[0], job[1], job[2], str(job[3])]
            running.append((job, subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True), time.time()))
        time.sleep(2)
        for item in list(running):
            job, proc, t0 = item
            if proc.poll() is None:
                continue
            running.remove(item)
            out = proc.stdout.read().strip().splitlines()
            if proc.returncode != 0 or not out:
                print(f"{'/'.join(map(str, job))}: failed (exit {proc.returncode})", file=sys.stderr)
                continue
            row = json.loads(out[-1])
            rows.append(row)
            with res_file.open("a") as f:
                f.write(json.dumps(row) + "\n")
            print(f"{row['regime']:>14} {row['clip']:>4} seed {row['seed']}: PSNR {row['psnr']:.2f} SSIM {row['ssim']:.4f} "
                  f"LPIPS {row['lpips']:.4f}, {row['n_gaussians']} Gaussians, {row['train_s']:.0f} s "
                  f"({time.time() - t0:.0f} s wall)", flush=True)
    text = summary(rows)
    (a.out / "summary.md").write_text(text)
    print(text)
    if plot_lr(rows, a.out / "position_lr.png"):
        print(f"plot: {a.out / 'position_lr.png'}")


if __name__ == "__main__":
    main()
