"""dvc.yaml lists, for every stage, the code it runs: the stage modules in its ``cmd`` and every
drawer_lib module they import, directly or through other drawer_lib modules, at module level
or inside a function. A library edit then reruns exactly the stages it can change."""

import ast
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
LIB = ROOT / "drawer_lib"


def _module_file(name: str) -> Path | None:
    """The file of an importable drawer_lib / stages module, or None for third-party ones."""
    if not name.split(".")[0] in ("drawer_lib", "stages"):
        return None
    p = ROOT.joinpath(*name.split("."))
    if p.with_suffix(".py").is_file():
        return p.with_suffix(".py")
    if (p / "__init__.py").is_file():
        return p / "__init__.py"
    return None


def _imports(path: Path) -> set[Path]:
    """Files of the drawer_lib / stages modules ``path`` imports (any scope), with the
    __init__.py of every package on the way (importing a.b.c runs a and a.b)."""
    out: set[Path] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path}:{node.lineno}: use absolute imports (this check reads them)"
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        for n in names:
            parts = n.split(".")
            for k in range(1, len(parts) + 1):
                f = _module_file(".".join(parts[:k]))
                if f is not None:
                    out.add(f)
    return out


def _closure(start: set[Path]) -> set[Path]:
    seen, todo = set(), list(start)
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        todo.extend(_imports(f) - seen)
    return seen


def _stages() -> dict[str, dict]:
    """Stage name -> its definition (the ``do`` block of a foreach, the body otherwise)."""
    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    return {name: st.get("do", st) for name, st in stages.items()}


def _covered(f: Path, deps: list[str]) -> bool:
    rel = f.relative_to(ROOT).as_posix()
    return any(rel == d or rel.startswith(d.rstrip("/") + "/") for d in deps)


def test_every_stage_lists_the_code_it_imports():
    missing = {}
    for name, st in _stages().items():
        cmds = st["cmd"] if isinstance(st["cmd"], list) else [st["cmd"]]
        mods = {w for c in cmds for w in c.split() if w.startswith("stages.")}
        assert mods, f"stage {name}: no `python -m stages.<module>` in its cmd"
        files = _closure({_module_file(m) for m in mods})
        deps = [d if isinstance(d, str) else next(iter(d)) for d in st.get("deps", [])]
        # drawer_lib/__init__.py holds only the package docstring and version (checked below)
        lack = sorted(f.relative_to(ROOT).as_posix() for f in files
                      if f != LIB / "__init__.py" and not _covered(f, deps))
        if lack:
            missing[name] = lack
    assert not missing, f"dvc.yaml stages import code they do not list as deps: {missing}"


def _call_name(call: ast.Call) -> str:
    return ast.unparse(call.func)


def test_package_root_holds_no_code_that_can_change_a_result():
    """drawer_lib/__init__.py is no stage's dep, so it may hold only ``__version__`` and the OpenMP
    wait policy, which decides whether idle threads spin and never a result (the appearance
    step's parameters have the same SHA-1 under both policies: docs/speed.md; tests/test_omp_policy.py)."""
    tree = ast.parse((LIB / "__init__.py").read_text())
    body = [n for n in tree.body if not (isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant))]
    for n in body:
        if isinstance(n, ast.Import):
            assert {a.name for a in n.names} <= {"os", "sys", "warnings"}, ast.unparse(n)
        elif isinstance(n, ast.Assign):
            assert [ast.unparse(t) for t in n.targets] in (["__version__"], ["_WAIT_POLICY"]), ast.unparse(n)
        elif isinstance(n, ast.FunctionDef):
            assert n.name == "omp_wait_policy", n.name
        elif isinstance(n, ast.If):  # the policy: only environment reads / writes and a warning
            calls = {_call_name(c) for c in ast.walk(n) if isinstance(c, ast.Call)}
            assert calls <= {"os.environ.setdefault", "sys.modules['torch'].get_num_threads", "warnings.warn"}, calls
        else:
            raise AssertionError(f"drawer_lib/__init__.py: unexpected statement {ast.unparse(n)[:80]}")


def test_the_check_sees_function_level_imports():
    """The appearance stage reaches drawer_lib/sdf only through an import inside a function."""
    files = _closure({_module_file("stages.appearance")})
    assert LIB / "sdf" / "io.py" in files


def test_a_detector_fit_lists_every_detector_key_but_the_seeds_and_the_averaging():
    """Each ``detector_fit@<seed>`` depends on the detector's keys one by one, all but those
    only the ``detector`` stage reads (``seeds``, ``average_*``): adding a seed or changing the
    averaging must not refit, and a key left off the list would let a changed setting keep a
    stale fit."""
    from dataclasses import fields

    from drawer_lib.detect.config import DetectorTrainConfig

    params = _stages()["detector_fit"]["params"]
    listed = {p.split(".", 1)[1] for p in params if isinstance(p, str) and p.startswith("detector.")}
    assert listed == {f.name for f in fields(DetectorTrainConfig)} - DetectorTrainConfig.NOT_FIT_KEYS
    assert DetectorTrainConfig.NOT_FIT_KEYS <= {f.name for f in fields(DetectorTrainConfig)}
    assert "detector" not in params and "seed" not in params  # the seed is the stage's own (its cmd)
    assert "${item}" in _stages()["detector_fit"]["cmd"]
