"""drawer_lib/paths.py is the one place that names outputs: it keeps the names the design's
contracts fix (evaluation outside this project reads them), resolves geometry variants, and
dvc.yaml reads it."""

from pathlib import Path

import yaml

from drawer_lib.paths import LAYOUT, ScenePaths, capture_name, stage_name

ROOT = Path(__file__).resolve().parent.parent


def test_layout_keeps_the_contract_names():
    sp = ScenePaths(Path("out"), "k")
    assert sp.capture == Path("out/k/capture") and sp.field == Path("out/k/sdf/field.pt")
    assert sp.mesh == Path("out/k/mesh/mesh.ply") and sp.parts == Path("out/k/articulate/parts.json")
    assert sp.metrics("evaluate") == Path("out/k/evaluate/metrics.json")
    assert sp.appearance_dir("free_gs") == Path("out/k/appearance/free_gs")
    assert capture_name("transforms") == "transforms.json" and capture_name("gt_parts") == "gt/parts.json"
    assert capture_name("gt_mesh") == "gt/mesh.ply" and capture_name("images") == "images"
    assert stage_name("sdf", "field") == "field.pt" and stage_name("mesh", "metrics") == "metrics.json"
    assert stage_name("sdf", "curve") == "curve.csv"


def test_geometry_variants_keep_sdf_and_mesh_apart_but_share_the_capture():
    v = ScenePaths(Path("out"), "k", "tsdf")
    assert v.field == Path("out/k/geometry/tsdf/sdf/field.pt") and v.mesh == Path("out/k/geometry/tsdf/mesh/mesh.ply")
    assert v.capture == Path("out/k/capture") and v.parts == Path("out/k/articulate/parts.json")


def test_every_entry_is_relative_and_under_its_stage():
    for stage, names in LAYOUT.items():
        if not isinstance(names, dict) or stage == "report":
            continue
        for key, rel in names.items():
            assert not rel.startswith("/") and ".." not in rel, (stage, key)
            if key != "dir" and stage not in ("appearance", "geometry"):
                assert rel.startswith(names["dir"] + "/"), (stage, key)


def test_dvc_yaml_reads_the_layout_instead_of_spelling_names():
    text = (ROOT / "dvc.yaml").read_text()
    assert "drawer_lib/paths.py:LAYOUT" in text and "drawer_lib/paths.py:BENCH" in text
    stages = yaml.safe_load(text)["stages"]
    for name, st in stages.items():
        st = st.get("do", st)
        for o in st.get("outs", []) + st.get("metrics", []) + st.get("plots", []):
            o = o if isinstance(o, str) else next(iter(o))
            assert "${LAYOUT." in o or "${BENCH." in o, (name, o)
