"""The rooms follow the data: no two packages of drawer_lib import each other and no modules
form an import cycle (imports at any scope count: a function-level import that dodges a cycle
is still a cycle); every output name is spelled in drawer_lib/paths.py only; scripts are plain
callers of the installed package; nothing cites documents a user of the repository lacks."""

import ast
import re
import subprocess
from collections import defaultdict
from pathlib import Path

import networkx as nx

from drawer_lib.paths import BENCH, LAYOUT

ROOT = Path(__file__).resolve().parent.parent
LIB = ROOT / "drawer_lib"


def _module(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module(p): p for p in LIB.rglob("*.py")}


def _imports(mod: str, path: Path) -> set[str]:
    """The drawer_lib modules ``mod`` imports, at any scope (the deepest module each name
    resolves to)."""
    out = set()
    is_pkg = path.name == "__init__.py"
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = mod.split(".") if is_pkg else mod.split(".")[:-1]
                base = ".".join(parent[:len(parent) - node.level + 1] + ([node.module] if node.module else []))
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        for n in names:
            while n and n not in MODULES:
                n = n.rpartition(".")[0]
            if n and n != mod and not mod.startswith(n + "."):
                out.add(n)
    return out


def _graph() -> nx.DiGraph:
    g = nx.DiGraph()
    for mod, path in MODULES.items():
        g.add_node(mod)
        g.add_edges_from((mod, t) for t in _imports(mod, path))
    return g


def _package(mod: str) -> str:
    """drawer_lib.<package> (a top-level module counts as its own package)."""
    return ".".join(mod.split(".")[:2])


def test_no_two_packages_import_each_other():
    edges = defaultdict(set)
    for a, b in _graph().edges:
        if _package(a) != _package(b):
            edges[_package(a)].add((a, b))
    pairs = sorted((p, q) for p in list(edges) for q in {_package(b) for _, b in edges[p]}
                   if p < q and any(_package(b) == p for _, b in edges.get(q, ())))
    detail = {f"{p} <-> {q}": sorted(e for e in edges[p] | edges[q] if {_package(e[0]), _package(e[1])} == {p, q})
              for p, q in pairs}
    assert not pairs, detail


def test_no_module_import_cycles():
    cycles = [sorted(c) for c in nx.strongly_connected_components(_graph()) if len(c) > 1]
    assert not cycles, cycles


def test_the_check_sees_function_level_imports():
    """The graph counts an import inside a function (the way cycles used to be dodged)."""
    src = MODULES["drawer_lib.articulation.estimators"]
    assert "drawer_lib.articulation.infer" in _imports("drawer_lib.articulation.estimators", src)


def _names(tree: dict) -> set[str]:
    out = set()
    for v in tree.values():
        if isinstance(v, dict):
            out |= _names(v)
        else:
            out.add(v.rsplit("/", 1)[-1])
    return out


# file names of the outputs (those with an extension: folder names like "model" or "renders" are
# words too common to search for)
OUTPUT_NAMES = {n for n in _names(LAYOUT) | _names(BENCH) if "." in n}


def _strings(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every string literal in ``path`` but docstrings, f-string parts included."""
    tree = ast.parse(path.read_text())
    docs = {id(n.body[0].value) for n in ast.walk(tree)
            if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and n.body
            and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
    return [(n.lineno, n.value) for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs]


def test_output_names_are_spelled_in_paths_py_only():
    assert {"twin.json", "scene.xml", "parts.json", "weights.json", "metrics.json"} <= OUTPUT_NAMES
    found = []
    for path in sorted([*LIB.rglob("*.py"), *(ROOT / "stages").glob("*.py")]):
        if path == LIB / "paths.py":
            continue
        for line, text in _strings(path):
            hit = [n for n in OUTPUT_NAMES if re.search(rf"(^|[/\s'\"(]){re.escape(n)}($|[\s'\")])", text)]
            if hit:
                found.append(f"{path.relative_to(ROOT)}:{line}: {hit}")
    assert not found, "\n".join(found)


def test_scripts_are_plain_callers_of_the_installed_package():
    bad = []
    for path in sorted((ROOT / "scripts").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and isinstance(node.func.value, ast.Attribute) and node.func.value.attr == "path"
                    and getattr(node.func.value.value, "id", None) == "sys"):
                bad.append(f"{path.name}:{node.lineno}: sys.path.{node.func.attr}")
            if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in ("tests", "helpers"):
                bad.append(f"{path.name}:{node.lineno}: imports from the tests")
    assert not bad, bad


def test_nothing_cites_what_users_do_not_have():
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    pattern = re.compile(r"DESIGN(\.md| §)|\.\./shared|[Ii]ssue \d+|reference §|drawer_method\.md|dvc_hydra\.md")
    hits = []
    for f in files:
        p = ROOT / f
        if p.suffix not in (".py", ".md", ".yaml", ".toml", ".sh", ".cfg") and p.name != "Makefile" or not p.is_file():
            continue
        if p == Path(__file__).resolve():
            continue
        for i, line in enumerate(p.read_text(errors="replace").splitlines(), 1):
            if pattern.search(line):
                hits.append(f"{f}:{i}: {line.strip()[:100]}")
    assert not hits, "\n".join(hits)
