"""Provenance of a map: the global attributes (spec text and digest, code digest, ball,
thresholds, step used, version and git commit, history), and the digest of the code that
computes a launch."""
from __future__ import annotations

import ast
import datetime as _dt
import functools
import hashlib
import os
import platform
import re
import subprocess
import tempfile
from pathlib import Path

from .. import _jit
from .._version import __version__
from ..store import CONVENTIONS, REFERENCES
from .plan import n_steps
from .spec import Spec


def git_commit() -> str | None:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=Path(__file__).parent,
                             capture_output=True, text=True, timeout=5)
        return out.stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


PACKAGE = Path(__file__).resolve().parent.parent
#: where the code digest starts: the modules a launch is computed, labelled and stored by; the
#: package modules they import (at any depth, lazy imports included) are followed from here.
#: The kernel subpackages are taken whole: some of their files are templates read as text.
COMPUTE_ROOTS = ("sweep/compute.py", "sweep/spec.py", "sweep/plan.py", "store.py")
COMPUTE_PACKAGES = ("physics", "integrate", "classify")


def _module_file(name: str) -> Path | None:
    """The file of package module `name` ('compose', 'classify.labels'), or None."""
    base = PACKAGE.joinpath(*name.split(".")) if name else PACKAGE
    for f in (base.with_suffix(".py"), base / "__init__.py"):
        if f.is_file():
            return f
    return None


def _imports(path: Path, tree: ast.AST) -> set:
    """Package modules that `path` imports (relative or as ballsurvey.x)."""
    rel = path.relative_to(PACKAGE).with_suffix("")
    pkg = list(rel.parts[:-1])  # the package the module is in
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[:len(pkg) - (node.level - 1)] if node.level > 1 else pkg
                mod = ".".join(base + ([node.module] if node.module else []))
            elif node.module and node.module.split(".")[0] == "ballsurvey":
                mod = node.module.partition(".")[2]
            else:
                continue
            found.add(mod)
            found.update(f"{mod}.{a.name}".strip(".") for a in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name.partition(".")[2] for a in node.names
                         if a.name.split(".")[0] == "ballsurvey")
    return found


def _strip_docstrings(tree: ast.AST) -> ast.AST:
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        first = body[0] if isinstance(body, list) and body else None
        if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                and isinstance(first.value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return tree


@functools.cache
def _module_code() -> dict:
    """{path relative to the package: its syntax tree without docstrings, dumped} of
    `compute_modules`."""
    todo = [PACKAGE / r for r in COMPUTE_ROOTS]
    todo += [f for d in COMPUTE_PACKAGES for f in sorted((PACKAGE / d).glob("*.py"))]
    seen: dict = {}
    while todo:
        f = todo.pop()
        if f in seen or f == PACKAGE / "__init__.py":
            continue
        tree = ast.parse(f.read_text(), str(f))
        todo += [g for g in map(_module_file, _imports(f, tree)) if g is not None]
        seen[f] = ast.dump(_strip_docstrings(tree))
    return {str(f.relative_to(PACKAGE)): code for f, code in seen.items()}


def compute_modules() -> tuple:
    """The package's source files that take part in computing a launch (paths relative to the
    package), sorted: `COMPUTE_ROOTS`, the kernel subpackages and every package module they
    import. The package's own `__init__.py` (the public API) is left out; its version is in the
    digest."""
    return tuple(sorted(_module_code()))


#: where `code_digest` keeps its last result, in the package's `__pycache__`: "key digest"
DIGEST_CACHE = "ballsurvey-code-digest.txt"


def _sources_key() -> str | None:
    """SHA-256 over the version, Python's version and the bytes of every .py file of the
    package (with its path): the same key, the same `code_digest`. None if one cannot be read."""
    h = hashlib.sha256(f"ballsurvey {__version__}\0{platform.python_version()}\0".encode())
    try:
        _jit.hash_files(h, sorted(PACKAGE.rglob("*.py")), PACKAGE)
    except OSError:
        return None
    return h.hexdigest()


@functools.cache
def code_digest() -> str:
    """SHA-256 over ballsurvey's version and the code of `compute_modules` (each file's syntax
    tree without docstrings: comments, blank lines and layout leave it unchanged). Recorded in a
    sweep's parts and map; a resume or an "up to date" needs the same digest, since launches
    computed by other code may give other results.

    Parsing those files takes about 0.1 s, a part of every sweep process's fixed cost: the
    result is kept in `DIGEST_CACHE` under `_sources_key` (the bytes of every source file) and
    read back while the sources are byte for byte the same; where it cannot be written, it is
    computed each time."""
    key = _sources_key()
    cache = PACKAGE / "__pycache__" / DIGEST_CACHE
    try:
        stored_key, stored = cache.read_text().split()
        if key is not None and stored_key == key and re.fullmatch(r"[0-9a-f]{64}", stored):
            return stored
    except (OSError, ValueError, UnicodeDecodeError):
        pass  # none yet, or unreadable: computed below
    h = hashlib.sha256(f"ballsurvey {__version__}\n".encode())
    code = _module_code()
    for rel in sorted(code):
        h.update(f"{rel}\n{code[rel]}\n".encode())
    digest = h.hexdigest()
    if key is not None:
        _keep(cache, f"{key} {digest}\n")
    return digest


def _keep(path: Path, text: str) -> None:
    """`text` into `path`, whole or not at all (written aside, then renamed over); nothing
    where it cannot be written (a read-only install)."""
    tmp = None
    try:
        path.parent.mkdir(exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".digest-", dir=path.parent)
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except OSError:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)


def global_attrs(spec: Spec, command: str) -> dict:
    commit = git_commit()
    now = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    attrs = {
        "Conventions": CONVENTIONS,
        "title": spec.title,
        "institution": "ballsurvey users",
        "source": f"ballsurvey {__version__}" + (f" (git {commit})" if commit else ""),
        "history": f"{now}: {command}",
        "references": REFERENCES,
        "comment": "Paths of a biased ball rolling without slipping; labels from the streaming "
                   "classifier (see flag_meanings of label).",
        "spec_toml": spec.text,
        "spec_digest": spec.digest,
        "code_digest": code_digest(),
        "run_T_s": spec.T, "run_dt_s_requested": spec.dt, "run_dt_s": spec.T / n_steps(spec),
        "run_method": spec.method, "run_observe_every": spec.observe_every,
        "run_rtol": spec.rtol, "run_atol": spec.atol, "run_mode": spec.mode,
        "run_cycles": spec.cycles, "run_backend": spec.backend,
    }
    for k, v in spec.ball.as_dict().items():
        unit = {"a": "m", "c": "m", "M": "kg", "A": "kg m2", "B": "kg m2", "g": "m s-2",
                "cut_height": "m"}[k]
        attrs[f"ball_{k}"] = v
        attrs[f"ball_{k}_units"] = unit
    for k, v in spec.thresholds.as_dict().items():
        attrs[f"classify_{k}"] = v
    return attrs
