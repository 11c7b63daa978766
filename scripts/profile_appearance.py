#!/usr/bin/env python
"""Where the time of one appearance training step goes: trains a variant for ``--steps`` steps on
a scene's capture and mesh (the outputs of ``dvc repro mesh@<scene>``) under cProfile and prints
seconds per step and the top functions by own time (compositor kernels, projection, autograd,
Adam, D-SSIM convolutions, ...). Density control starts at step 0 so that the Gaussian count
reaches its cap (~50k on kitchen_small) within a few hundred steps, as in the later part of a
real run; no evaluation, nothing written.

    python scripts/profile_appearance.py [--scene kitchen_small] [--variant movable_gs_ste] [--steps 300] [--top 25]
"""

import argparse
import cProfile
import pstats
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="kitchen_small")
    ap.add_argument("--variant", default="movable_gs_ste", help="a file of conf/appearance_variant/")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--top", type=int, default=25)
    args = ap.parse_args()
    if args.steps < 1:
        ap.error(f"--steps {args.steps}: must be at least 1")

    import trimesh
    from hydra import compose, initialize_config_dir

    from drawer_lib.config.typed import to_typed
    from drawer_lib.io.capture import load_capture
    from drawer_lib.paths import ScenePaths
    from drawer_lib.splat.config import AppearanceConfig
    from drawer_lib.splat.train import prepare, train_gaussians

    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"scene={args.scene}", f"appearance_variant={args.variant}",
                                                       f"appearance.steps={args.steps}", "appearance.eval_every=1000000",
                                                       "appearance.strategy.refine_start=0"])
    app = to_typed(AppearanceConfig, cfg.appearance, "appearance")
    sp = ScenePaths(ROOT / cfg.paths.out, args.scene)
    mesh_path = sp.mesh
    if not mesh_path.is_file():
        raise SystemExit(f"{mesh_path}: missing (run `dvc repro mesh@{args.scene}` first)")
    cap = load_capture(sp.capture)
    sc = prepare(cap, trimesh.load(mesh_path, process=False), app)
    prof = cProfile.Profile()
    prof.enable()
    st = train_gaussians(cap, sc, app, 0)
    prof.disable()
    print(f"{app.variant}: {st.steps} steps in {st.train_s:.1f} s = {1000 * st.train_s / st.steps:.1f} ms/step, "
          f"{st.params.face.shape[0]} Gaussians at the end")
    pstats.Stats(prof).sort_stats("tottime").print_stats(args.top)


if __name__ == "__main__":
    main()
