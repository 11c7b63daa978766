"""CI's dashboard (drawer_lib/report/ci.py): the headline keys of a run, and the gates: a metric
worse than the baseline beyond its tolerance, or gone, fails; better or within passes."""

import json

from drawer_lib.paths import ScenePaths
from drawer_lib.report.ci import GATES, compare, dashboard, headline


def test_headline_reads_the_stage_and_variant_metrics(tmp_path):
    sp = ScenePaths(tmp_path, "s")
    for st, m in (("mesh", {"chamfer_l1": 0.004, "fscore_2cm": 0.9, "faces_out": 10, "wall_s": 2.0}),
                  ("evaluate", {"precision": 0.8, "recall": 0.7, "ea_score": 0.9})):
        sp.metrics(st).parent.mkdir(parents=True)
        sp.metrics(st).write_text(json.dumps(m))
    (sp.appearance_dir("v") / "metrics.json").parent.mkdir(parents=True)
    (sp.appearance_dir("v") / "metrics.json").write_text(json.dumps({"psnr": 30.0, "ssim": 0.9, "lpips": 0.1}))
    h = headline(tmp_path, ["s"], ["v", "absent"], ["tsdf"])
    assert h == {"s/mesh:chamfer_l1": 0.004, "s/mesh:fscore_2cm": 0.9, "s/mesh:wall_s": 2.0,
                 "s/evaluate:precision": 0.8, "s/evaluate:recall": 0.7, "s/evaluate:ea_score": 0.9,
                 "s/appearance/v:psnr": 30.0, "s/appearance/v:ssim": 0.9, "s/appearance/v:lpips": 0.1}


def test_gates_fail_regressions_only():
    base = {"s/mesh:chamfer_l1": 0.004, "s/appearance/v:psnr": 30.0, "s/evaluate:recall": 0.8, "s/mesh:wall_s": 2.0}
    tol_psnr = GATES["psnr"].abs_tol
    ok = {"s/mesh:chamfer_l1": 0.0041, "s/appearance/v:psnr": 30.0 - 0.9 * tol_psnr, "s/evaluate:recall": 0.95,
          "s/mesh:wall_s": 50.0}  # within tolerance, better, and an ungated wall time
    assert compare(ok, base)[1] == []
    bad = dict(ok, **{"s/appearance/v:psnr": 30.0 - 1.1 * tol_psnr})
    del bad["s/evaluate:recall"]
    rows, regs = compare(bad, base)
    assert len(regs) == 2 and any("psnr" in r for r in regs) and any("not in this run" in r for r in regs)
    md, _ = dashboard(bad, base, "t")
    assert "REGRESSION" in md and "missing" in md and "**2 regression(s)**" in md
    # chamfer: lower is better, a 20 % relative tolerance plus 0.2 mm
    assert compare({"s/mesh:chamfer_l1": 0.004 * 1.2 + 2e-4 + 1e-6}, {"s/mesh:chamfer_l1": 0.004})[1]
