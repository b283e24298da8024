"""Layering: the library below, the harness above (docs/modules.md).

The library is every module of ``qfg`` outside ``qfg.harness`` (and the ``python -m qfg`` entry
point, which belongs to the command). It must not import the harness or matplotlib when imported
(figures are the harness's business, and a notebook must keep its own backend), and no two
``qfg`` modules may import each other, directly or through others.
"""

import ast
import re
import subprocess
import sys
from pathlib import Path

import networkx as nx

import qfg

ROOT = Path(qfg.__file__).resolve().parent
HARNESS = "qfg.harness"
ENTRY = {"qfg.__main__"}


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(ROOT.rglob("*.py"))
            if "__pycache__" not in p.parts and not any(x.startswith("_tensors") or
                                                          x.startswith("_presets") for x in p.parts)}


MODULES = _modules()
LIBRARY = sorted(m for m in MODULES if not (m == HARNESS or m.startswith(HARNESS + "."))
                 and m not in ENTRY)
#: what importing the library means: every module but the ``python -m`` entry points
IMPORTABLE = [m for m in LIBRARY if not m.endswith(".__main__")]


def _imports(name: str, path: Path):
    """(imported module, line, at module level?) for every import statement of a module; relative
    imports resolved, ``from pkg import sub`` read as the submodule ``pkg.sub`` where it is one."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    top_level = set()
    for node in tree.body:  # module level, including inside if/try blocks at module level
        top_level.update(id(n) for n in _walk_outside_functions(node))
    skip = {id(n) for t in ast.walk(tree) if _type_checking_only(t) for n in ast.walk(t)}
    for node in ast.walk(tree):
        if id(node) in skip:  # annotations only, never executed
            continue
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, node.lineno, id(node) in top_level
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            for a in node.names:
                full = f"{mod}.{a.name}"
                yield (full if full in MODULES else mod), node.lineno, id(node) in top_level


def _type_checking_only(node) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _walk_outside_functions(node):
    if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
        return
    yield node
    for child in ast.iter_child_nodes(node):
        yield from _walk_outside_functions(child)


def test_the_module_list_is_complete():
    assert "qfg.partitions" in LIBRARY and "qfg.composition.store" in LIBRARY
    assert "qfg.harness.runner" in MODULES and "qfg.harness.runner" not in LIBRARY


def test_library_imports_neither_the_harness_nor_matplotlib_at_import_time():
    bad = []
    for name in LIBRARY:
        for mod, line, top in _imports(name, MODULES[name]):
            if mod == HARNESS or mod.startswith(HARNESS + "."):
                bad.append(f"{name}:{line} imports {mod}")  # not even lazily: one way only
            elif top and (mod == "matplotlib" or mod.startswith("matplotlib.")):
                bad.append(f"{name}:{line} imports {mod} at import time")
    assert not bad, "\n".join(bad)


def test_importing_every_library_module_loads_no_matplotlib_and_no_harness():
    code = ("import importlib, sys\n"
            f"for m in {IMPORTABLE!r}:\n    importlib.import_module(m)\n"
            "bad = sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib'\n"
            "             or m.startswith('qfg.harness'))\n"
            "print(len(bad), bad[:5])")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("0 "), r.stdout


def test_plotting_sets_no_backend_at_import():
    code = ("import matplotlib, qfg.harness.plotting, qfg.harness.plotting_mrclam\n"
            "import qfg.harness.studies as s; s.studies()\n"
            "print(matplotlib.rcParams._get_backend_or_none() or 'unset')")
    env = {k: v for k, v in __import__("os").environ.items() if k != "MPLBACKEND"}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                       env=env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "unset"


def _graph() -> nx.DiGraph:
    g = nx.DiGraph()
    for name, path in MODULES.items():
        g.add_node(name)
        for mod, _, _ in _imports(name, path):
            if mod not in MODULES or mod == name:
                continue
            # importing an enclosing package is implied by importing the module itself
            if name.startswith(mod + "."):
                continue
            g.add_edge(name, mod)
    return g


def test_no_import_cycles_among_qfg_modules():
    cycles = sorted(sorted(c) for c in nx.simple_cycles(_graph()))
    assert not cycles, f"import cycles: {cycles}"


def test_the_harness_is_above_the_library():
    g = _graph()
    assert not [(a, b) for a, b in g.edges if a in LIBRARY and b not in LIBRARY]
    assert any(a.startswith(HARNESS) and b in LIBRARY for a, b in g.edges)  # one way


def test_the_joint_map_reads_no_dataset_and_the_loader_needs_no_solver():
    # the MRCLAM adapter (qfg.datasets.mrclam.joint_map) sits above both the joint map and the
    # loader: the joint map takes measurements, not files, and loading data solves nothing
    g = _graph()
    joint = [m for m in LIBRARY if m == "qfg.joint" or m.startswith("qfg.joint.")]
    assert "qfg.joint.start" in joint
    below = {b for a in joint for b in nx.descendants(g, a)}
    assert not [m for m in below if m.startswith("qfg.datasets")]
    assert g.has_edge("qfg.datasets.mrclam.joint_map", "qfg.joint")
    assert not nx.has_path(g, "qfg.datasets.mrclam", "qfg.joint")


#: the longest module a file may be unless docs/modules.md names it with the one concept it holds
MAX_MODULE_LINES = 800


def test_no_module_is_over_800_lines_unless_docs_modules_names_it():
    doc = (ROOT.parent / "docs" / "modules.md").read_text(encoding="utf-8")
    section = doc.split("## Modules over 800 lines", 1)[1].split("\n## ", 1)[0]
    named = set(re.findall(r"`(qfg/[\w/]+\.py)`", section))
    long = {str(p.relative_to(ROOT.parent)) for p in MODULES.values()
            if len(p.read_text(encoding="utf-8").splitlines()) > MAX_MODULE_LINES}
    n = MAX_MODULE_LINES
    assert long <= named, f"over {n} lines and not in docs/modules.md: {sorted(long - named)}"
    assert named <= long, f"named in docs/modules.md but not over {n} lines: {sorted(named - long)}"
