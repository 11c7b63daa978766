"""VolSDF rendering numerics: extreme beta and SDF values, float64 gradcheck of the weights,
and the annealing schedule."""

import math

import pytest
import torch

from drawer_lib.sdf.render import beta_schedule, laplace_density, ray_box, render_weights, sample_pdf


def naive_density(s: torch.Tensor, beta: float) -> torch.Tensor:
    """VolSDF's formula as written in the paper (overflows for small beta)."""
    return torch.where(s <= 0, 1 - 0.5 * torch.exp(s / beta), 0.5 * torch.exp(-s / beta)) / beta


@pytest.mark.parametrize("beta", [1e-5, 1e-3, 0.05, 1.0])
def test_density_finite_with_finite_grads_at_extremes(beta):
    s = torch.tensor([-1e3, -10.0, -1e-6, 0.0, 1e-6, 10.0, 1e3], dtype=torch.float32, requires_grad=True)
    sig = laplace_density(s, beta)
    assert torch.isfinite(sig).all()
    assert (sig >= 0).all() and (sig <= 1.0 / beta * (1 + 1e-6)).all()
    sig.sum().backward()
    assert torch.isfinite(s.grad).all()
    # deep inside: sigma -> 1/beta; far outside: sigma -> 0
    assert sig[0].item() == pytest.approx(1.0 / beta, rel=1e-6)
    assert sig[-1].item() == pytest.approx(0.0, abs=1e-30)


def test_density_matches_the_paper_formula_where_that_is_finite():
    s = torch.linspace(-0.2, 0.2, 101, dtype=torch.float64)
    for beta in (0.01, 0.05, 0.3):
        torch.testing.assert_close(laplace_density(s, beta), naive_density(s, beta), rtol=1e-12, atol=0)
    # far outside at tiny beta the naive form's unselected branch overflows (inf), and its
    # gradient through torch.where is NaN; the stable form stays finite
    s = torch.tensor([1e3], requires_grad=True)
    naive_density(s, 1e-5).sum().backward()
    assert not torch.isfinite(s.grad).all()
    s.grad = None
    laplace_density(s, 1e-5).sum().backward()
    assert torch.isfinite(s.grad).all()


def test_weights_extreme_inputs_finite_and_sum_at_most_one():
    sigma = laplace_density(torch.tensor([[1e3, 1e-3, -1e-3, -1e3] * 4]), 1e-5)  # 0 .. 1e5
    deltas = torch.tensor([[1e-6, 1e-2, 1.0, 10.0] * 4])
    sigma.requires_grad_(True)
    w = render_weights(sigma, deltas)
    assert torch.isfinite(w).all() and (w >= 0).all() and w.sum() <= 1 + 1e-6
    w.sum().backward()
    assert torch.isfinite(sigma.grad).all()


def test_weights_opaque_first_sample_takes_everything():
    w = render_weights(torch.tensor([[1e5, 1e5, 1e5]]), torch.tensor([[0.1, 0.1, 0.1]]))
    torch.testing.assert_close(w, torch.tensor([[1.0, 0.0, 0.0]]))


def test_weights_match_the_product_form():
    g = torch.Generator().manual_seed(0)
    sigma = torch.rand(5, 9, generator=g, dtype=torch.float64) * 20
    delta = torch.rand(5, 9, generator=g, dtype=torch.float64) * 0.2
    alpha = 1 - torch.exp(-sigma * delta)
    T = torch.cumprod(torch.cat([torch.ones(5, 1, dtype=torch.float64), 1 - alpha[:, :-1]], 1), 1)
    torch.testing.assert_close(render_weights(sigma, delta), T * alpha, rtol=1e-12, atol=1e-15)


def test_gradcheck_rendering_weights_float64():
    g = torch.Generator().manual_seed(1)
    s = (torch.randn(3, 6, generator=g, dtype=torch.float64) * 0.05).requires_grad_(True)
    delta = (torch.rand(3, 6, generator=g, dtype=torch.float64) * 0.05 + 0.01).requires_grad_(True)
    beta = torch.tensor(0.02, dtype=torch.float64, requires_grad=True)
    fn = lambda s, d, b: render_weights(laplace_density(s, b), d)  # noqa: E731
    assert torch.autograd.gradcheck(fn, (s, delta, beta), eps=1e-7, atol=1e-6)


def test_beta_schedule_endpoints_and_monotone():
    b = [beta_schedule(k, 100, 0.05, 0.002) for k in range(0, 101, 10)]
    assert b[0] == pytest.approx(0.05) and b[-1] == pytest.approx(0.002)
    assert all(x > y for x, y in zip(b, b[1:]))
    assert beta_schedule(500, 100, 0.05, 0.002) == pytest.approx(0.002)


def test_ray_box_hits_and_misses():
    o = torch.tensor([[-2.0, 0.5, 0.5], [-2.0, 5.0, 0.5], [0.5, 0.5, 0.5]])
    d = torch.tensor([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    tn, tf = ray_box(o, d, torch.zeros(3), torch.ones(3), near=0.01)
    assert tn[0].item() == pytest.approx(2.0) and tf[0].item() == pytest.approx(3.0)
    assert tf[1] <= tn[1]  # miss
    assert tn[2].item() == pytest.approx(0.01) and tf[2].item() == pytest.approx(0.5)


def test_sample_pdf_follows_the_weights():
    bins = torch.linspace(0, 1, 11)[None].repeat(2, 1)
    w = torch.zeros(2, 10)
    w[0, 3] = 1.0
    w[1, 7] = 1.0
    t = sample_pdf(bins, w, 64, det=True)
    assert ((t[0] >= 0.3 - 1e-3) & (t[0] <= 0.4 + 1e-3)).float().mean() > 0.95
    assert ((t[1] >= 0.7 - 1e-3) & (t[1] <= 0.8 + 1e-3)).float().mean() > 0.95
    assert math.isfinite(float(t.sum()))
