"""Who may import whom (docs/contributing.md, "Layout"), checked on every module's imports with
`ast`, including the kernel module sources that integrate/ generates and binds at run time.

    physics/      imports nothing of ours but _jit
    integrate/    physics/ and itself (generated kernel sources included)
    classify/     physics/ and itself
    then layers, each importing only its own layer or lower ones:
    0 _jit, _version, axes, limits, ball   1 physics   2 integrate, classify
    3 compose, units, quadrature, schema   4 sweep, store, simulate
    5 plot, query, find, paper, accuracy, bench, refine, period, gallery, explore
    6 cli   7 __main__
The package root (`ballsurvey/__init__.py`) may be imported for `__version__` only. It is the
public face: for library use it binds every public name as it is imported, so a room below it
takes `__version__` from `_version` (importing the root would close a cycle).

No import cycle anywhere: in the graph of every import between the package's modules, at module
level and inside functions, with the names the root binds and the kernel modules bound at run
time, no module reaches itself.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

import ballsurvey
from ballsurvey.integrate import ensemble
from ballsurvey.integrate.tableaus import FIXED_STEP

PKG = Path(ballsurvey.__file__).resolve().parent

LAYER = {
    "_jit": 0, "_version": 0, "axes": 0, "limits": 0, "ball": 0,
    "physics": 1,
    "integrate": 2, "classify": 2,
    "compose": 3, "units": 3, "quadrature": 3, "schema": 3,
    "sweep": 4, "store": 4, "simulate": 4,
    "plot": 5, "query": 5, "find": 5, "paper": 5, "accuracy": 5, "bench": 5, "refine": 5,
    "period": 5, "gallery": 5, "api": 5, "explore": 5, "fit": 5, "synthetic": 5, "animate": 5,
    "cli": 6, "__main__": 7,
}
#: rooms that may import only the rooms named (besides themselves)
ONLY = {"physics": {"_jit"}, "integrate": {"physics", "_jit"}, "classify": {"physics", "_jit"},
        "_jit": {"_version"}, "_version": set(), "axes": set(), "limits": set(), "ball": set()}


def room(module: str) -> str:
    """'ballsurvey.integrate.ensemble' -> 'integrate'; 'ballsurvey.cli' -> 'cli'."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _is_module(dotted: str) -> bool:
    rel = Path(*dotted.split(".")[1:]) if "." in dotted else Path()
    return (PKG / rel).with_suffix(".py").is_file() or (PKG / rel / "__init__.py").is_file()


def imports_of(source: str, module: str, is_package: bool = False) -> list[tuple[str, list]]:
    """(imported ballsurvey module, names) for every import in `source`, anywhere in it."""
    out = []
    base = module.split(".") if is_package else module.split(".")[:-1]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names if a.name.split(".")[0] == "ballsurvey"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parent = base[:len(base) - node.level + 1]
                target = ".".join(parent + ([node.module] if node.module else []))
            elif node.module and node.module.split(".")[0] == "ballsurvey":
                target = node.module
            else:
                continue
            names = [a.name for a in node.names]
            subs = [f"{target}.{n}" for n in names if _is_module(f"{target}.{n}")]
            rest = [n for n in names if not _is_module(f"{target}.{n}")]
            out += [(s, []) for s in subs]
            if rest:
                out.append((target, rest))
    return out


def violations(source: str, module: str, is_package: bool = False) -> list[str]:
    me = room(module)
    bad = []
    for target, names in imports_of(source, module, is_package):
        them = room(target)
        if them == me:
            continue
        if target == "ballsurvey":
            if set(names) <= {"__version__"}:
                continue
            bad.append(f"{module} imports the package root for {names}")
            continue
        if me in ONLY:
            if them not in ONLY[me]:
                bad.append(f"{module} ({me}/) imports {target}: {me} may import only "
                           f"{sorted(ONLY[me]) or 'nothing of ours'}")
            continue
        if them not in LAYER or LAYER[them] > LAYER.get(me, -1):
            bad.append(f"{module} (layer {LAYER.get(me)}) imports {target} "
                       f"(layer {LAYER.get(them)})")
    return bad


def _modules():
    for f in sorted(PKG.rglob("*.py")):
        rel = f.relative_to(PKG).with_suffix("")
        parts = [p for p in rel.parts if p != "__init__"]
        yield ".".join(["ballsurvey", *parts]), f.read_text(), f.name == "__init__.py"


def test_every_room_is_in_the_table():
    rooms = {room(m) for m, _, _ in _modules()} - {""}
    assert rooms <= set(LAYER), f"rooms missing from the layer table: {rooms - set(LAYER)}"


@pytest.mark.parametrize("module,source,is_pkg", list(_modules()), ids=lambda v: v
                         if isinstance(v, str) and v.startswith("ballsurvey") else "")
def test_imports_follow_the_rules(module, source, is_pkg):
    if module == "ballsurvey":
        return  # the package root: the public API (Ball, LABELS, Thresholds, simulate)
    assert violations(source, module, is_pkg) == []


@pytest.mark.parametrize("method", sorted(FIXED_STEP))
def test_generated_kernel_sources_import_only_physics_and_integrate(method):
    src = ensemble.kernel_module_source(method)
    assert violations(src, "ballsurvey.integrate.generated") == []
    # and the adaptive template, read as text and bound the same way
    tmpl = (PKG / "integrate" / "adaptive_kernel.py").read_text()
    assert violations(tmpl, "ballsurvey.integrate.adaptive_kernel") == []


@pytest.mark.parametrize("module,source", [
    ("ballsurvey.integrate.x", "from ..classify.observer import observe"),
    ("ballsurvey.integrate.x", "from ballsurvey.classify import labels"),
    ("ballsurvey.integrate.x", "def f():\n    from ..compose import OBSERVER"),
    ("ballsurvey.physics.x", "from ..ball import Ball"),
    ("ballsurvey.classify.x", "from ..integrate import outcome"),
    ("ballsurvey.store", "from .cli import main"),
    ("ballsurvey.compose", "from .sweep import load_spec"),
    ("ballsurvey.ball", "from . import simulate"),
])
def test_the_checker_catches_a_broken_rule(module, source):
    assert violations(source, module) != []


def import_graph() -> dict[str, set[str]]:
    """{module: the package modules it imports}, every import counted, module level or inside a
    function; the root's public names (bound with importlib) and the kernel modules
    integrate/ binds at run time (generated sources, the adaptive template) included."""
    graph = {}

    def owner(target: str) -> str:  # 'ballsurvey.store.RESULT' -> 'ballsurvey.store'
        while "." in target and not _is_module(target):
            target = target.rsplit(".", 1)[0]
        return target

    for module, source, is_pkg in _modules():
        out = graph.setdefault(module, set())
        out.update(owner(t) for t, _ in imports_of(source, module, is_pkg))
        for node in ast.walk(ast.parse(source)):  # importlib.import_module(".name", __name__)
            if (isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "import_module"
                    and node.args and isinstance(node.args[0], ast.Constant)
                    and str(node.args[0].value).startswith(".") and is_pkg):
                out.add(owner(module + node.args[0].value))
    graph["ballsurvey"] |= {f"ballsurvey.{m}" for m in ballsurvey._PUBLIC.values()}
    for method in sorted(FIXED_STEP):
        kernel = f"ballsurvey.integrate.<{method} kernel>"
        graph["ballsurvey.integrate.ensemble"].add(kernel)
        graph[kernel] = {owner(t) for t, _ in imports_of(ensemble.kernel_module_source(method),
                                                         "ballsurvey.integrate.generated")}
    graph["ballsurvey.integrate.adaptive"].add("ballsurvey.integrate.adaptive_kernel")
    for module, out in graph.items():
        out.discard(module)
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Cycles [a, b, ..., a]: in each strongly connected group of modules (Tarjan's), the
    shortest through each of its modules; shortest first."""
    index, low, stack, on_stack, groups = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = {stack.pop()}
            while v not in group:
                group.add(stack.pop())
            on_stack.difference_update(group)
            if len(group) > 1:
                groups.append(group)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    cycles = []
    for group in groups:  # the shortest way back to each module of the group, inside the group
        for start in sorted(group):
            paths, todo, found = {start: [start]}, [start], None
            while todo and not found:
                v = todo.pop(0)
                for w in sorted(graph[v] & group):
                    if w == start:
                        found = paths[v] + [start]
                        break
                    if w not in paths:
                        paths[w] = paths[v] + [w]
                        todo.append(w)
            k = found.index(min(found))  # each cycle once, from its first module by name
            cycle = found[k:-1] + found[:k] + [found[k]]
            if cycle not in cycles:
                cycles.append(cycle)
    return sorted(cycles, key=len)


def test_no_import_cycle():
    cycles = import_cycles(import_graph())
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_the_cycle_finder_names_a_cycle():
    graph = import_graph()
    assert "ballsurvey.sweep.engine" in graph["ballsurvey"]  # the root's public names count
    graph["ballsurvey.store"].add("ballsurvey.sweep.spec")  # the axes' table from the spec,
    graph["ballsurvey.sweep.spec"].add("ballsurvey.store")  # the variables' from the store
    cycles = import_cycles(graph)
    assert ["ballsurvey.store", "ballsurvey.sweep.spec", "ballsurvey.store"] in cycles, cycles
    graph = import_graph()
    graph["ballsurvey._jit"].add("ballsurvey")  # a room below the root importing it
    assert any(c[0] == "ballsurvey" and "ballsurvey._jit" in c for c in import_cycles(graph))


def test_ruff_is_clean():
    """ruff (configured in pyproject.toml) over src/ and tests/, where ruff is installed (it is in
    the `test` extra)."""
    import shutil
    import subprocess
    import sys

    exe = shutil.which("ruff") or str(Path(sys.executable).with_name("ruff"))
    if not Path(exe).is_file():
        pytest.skip("ruff is not installed (pip install -e '.[test]')")
    r = subprocess.run([exe, "check", "--no-cache", "src", "tests"], cwd=PKG.parents[1],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
