"""Density control keeps faces, parameters and Adam moments row-aligned; children stay on their
parent's face; the face guard never empties a face."""

import torch

from drawer_lib.splat.anchored import face_frames, init_anchored
from drawer_lib.splat.strategy import MeshAnchoredStrategy


def setup(n_faces=6, frozen=()):
    g = torch.Generator().manual_seed(0)
    V = torch.rand(n_faces * 3, 3, generator=g)
    F = torch.arange(n_faces * 3).view(n_faces, 3)
    fr = face_frames(V, F)
    p = init_anchored(fr, torch.rand(n_faces, 3, generator=g))
    groups = []
    for name, t in p.trainable().items():
        par = torch.nn.Parameter(t.clone(), requires_grad=name not in frozen)
        setattr(p, name, par)
        if name not in frozen:
            groups.append({"params": [par], "lr": 1e-3, "name": name})
    opt = torch.optim.Adam(groups)
    # one step so that Adam has moments
    loss = sum((t ** 2).sum() for t in p.trainable().values() if t.requires_grad)
    loss.backward()
    opt.step()
    return fr, p, opt


def rows_aligned(p, opt):
    n = p.face.shape[0]
    assert all(t.shape[0] == n for t in p.trainable().values())
    for group in opt.param_groups:
        (par,) = group["params"]
        assert par.shape[0] == n and getattr(p, group["name"]) is par
        for k, v in opt.state[par].items():
            if torch.is_tensor(v) and v.dim() > 0:
                assert v.shape == par.shape, (group["name"], k)


def test_split_and_dup_keep_rows_aligned_and_children_on_the_parent_face():
    fr, p, opt = setup()
    s = MeshAnchoredStrategy(refine_start=0, refine_every=1, refine_stop=10, size_thresh=0.05)
    n = p.face.shape[0]
    absgrad = torch.zeros(n, 2)
    absgrad[[0, 2, 4]] = 1.0  # high gradient
    state = s.initialize_state()
    s.step_post_backward(state, absgrad, torch.ones(n, dtype=torch.int32), 100)
    scales = torch.full((n, 3), 0.01)
    scales[[0, 2]] = 0.2  # big -> split; 4 small -> dup
    old_faces = p.face.clone()
    out = s.step_post_optimizer(state, 1, p, fr, scales, opt, torch.Generator().manual_seed(0))
    assert out["split"] == 2 and out["dup"] == 1
    assert p.face.shape[0] == n - 2 + 4 + 1
    rows_aligned(p, opt)
    assert sorted(p.face.tolist()) == sorted(old_faces.tolist() + [0, 2, 4])  # children on their parents' faces
    # new rows start with zero Adam moments, kept rows keep theirs
    st = opt.state[p.sh_dc]
    assert torch.all(st["exp_avg"][-5:] == 0) and torch.any(st["exp_avg"][:2] != 0)
    # split children: scales / 1.6 of the parent's clipped scale
    ls = p.log_scales.detach()
    assert torch.allclose(ls[-5:-1].exp(), torch.full((4, 3), 0.2 / 1.6))


def test_static_gaussians_are_duplicated_not_split():
    fr, p, opt = setup(frozen=("means_2d", "elevate"))  # static: positions are not optimised
    s = MeshAnchoredStrategy(refine_start=0, refine_every=1, refine_stop=10, size_thresh=0.05)
    n = p.face.shape[0]
    state = s.initialize_state()
    s.step_post_backward(state, torch.ones(n, 2), torch.ones(n, dtype=torch.int32), 100)
    pos = p.means_2d.detach().clone()
    out = s.step_post_optimizer(state, 1, p, fr, torch.full((n, 3), 0.2), opt, torch.Generator(), allow_split=False)
    assert out["split"] == 0 and out["dup"] == n
    assert torch.equal(p.means_2d.detach()[n:], pos)  # copies stay where the originals are
    rows_aligned(p, opt)
    assert not p.means_2d.requires_grad


def test_cull_with_face_guard_and_opacity_reset():
    fr, p, opt = setup()
    s = MeshAnchoredStrategy(refine_start=0, refine_every=1, refine_stop=10, reset_every=5, cull_alpha=0.5)
    n = p.face.shape[0]
    with torch.no_grad():
        p.opacity_logit[:] = 3.0
        p.opacity_logit[1] = -5.0  # face 1's only Gaussian: kept by the guard
    # give face 2 a second, transparent Gaussian by duplication, then cull it
    state = s.initialize_state()
    s.step_post_backward(state, torch.zeros(n, 2), torch.ones(n, dtype=torch.int32), 100)
    out = s.step_post_optimizer(state, 1, p, fr, torch.full((n, 3), 0.01), opt, torch.Generator())
    assert out["culled"] == 0 and p.face.shape[0] == n
    rows_aligned(p, opt)
    s.step_post_optimizer(state, 5, p, fr, torch.full((n, 3), 0.01), opt, torch.Generator())  # reset step
    assert torch.all(torch.sigmoid(p.opacity_logit.detach()) <= 0.2 + 1e-6)
    assert torch.all(opt.state[p.opacity_logit]["exp_avg"] == 0)


def test_cull_removes_a_transparent_gaussian_when_its_face_keeps_another():
    fr, p, opt = setup()
    s = MeshAnchoredStrategy(refine_start=0, refine_every=1, refine_stop=10, cull_alpha=0.5, size_thresh=1.0)
    n = p.face.shape[0]
    with torch.no_grad():
        p.opacity_logit[:] = 3.0
    ag = torch.zeros(n, 2)
    ag[0] = 1.0
    state = s.initialize_state()
    s.step_post_backward(state, ag, torch.ones(n, dtype=torch.int32), 100)
    s.step_post_optimizer(state, 1, p, fr, torch.full((n, 3), 0.01), opt, torch.Generator())  # duplicates row 0 (face 0)
    assert p.face.tolist().count(0) == 2
    with torch.no_grad():
        p.opacity_logit[-1] = -5.0
    out = s.step_post_optimizer(state, 2, p, fr, torch.full((n + 1, 3), 0.01), opt, torch.Generator())
    assert out["culled"] == 1 and p.face.tolist().count(0) == 1
    rows_aligned(p, opt)


def test_strategy_is_the_config_and_state_lives_apart():
    """gsplat's pattern: the frozen dataclass is the config value, the running statistics come
    from initialize_state(); every knob (reset_to, split_shrink included) is settable from the
    params, and `strategy: null` turns density control off."""
    import dataclasses

    import pytest

    from drawer_lib.config.typed import to_typed
    from drawer_lib.errors import ConfigError
    from drawer_lib.splat.config import AppearanceConfig

    s = MeshAnchoredStrategy()
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.reset_to = 0.5
    a, b = s.initialize_state(), s.initialize_state()
    s.step_post_backward(a, torch.ones(3, 2), torch.ones(3, dtype=torch.int32), 10)
    assert a["grad_sum"] is not None and b["grad_sum"] is None  # states are independent
    cfg = to_typed(AppearanceConfig, {"strategy": {"reset_to": 0.3, "split_shrink": 2.0}}, "appearance", strict=False)
    assert cfg.strategy.reset_to == 0.3 and cfg.strategy.split_shrink == 2.0 and cfg.strategy.refine_every == 100
    assert to_typed(AppearanceConfig, {"strategy": None}, "appearance", strict=False).strategy is None
    with pytest.raises(ConfigError, match="split_shrink"):
        MeshAnchoredStrategy(split_shrink=1.0)
