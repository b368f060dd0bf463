"""Parts and resume: one writer per output (a lock), the parts folder (manifest, one verified
part per finished chunk, one partial part per chunk interrupted by Ctrl-C), and what is on disk
when a run starts (`prepare_output`: refuse to mix specs, verify parts, find what is done).

Each part records its chunk, launch range and spec digest and carries a SHA-256 checksum; parts
are written atomically (a private temporary file, fsync, rename)."""
from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import re
import shutil
import stat
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import __version__
from ..limits import InputError
from ..store import RESULT_VARIABLES
from .plan import plan_chunks
from .spec import Spec

PARTS_SUFFIX = ".parts"
LOCK_SUFFIX = ".lock"
MANIFEST = "manifest.json"
PART_FORMAT = 2


class UpToDate(Exception):
    """The output exists and was made by the same spec: nothing to do."""


class OutputRefused(InputError, FileExistsError):
    """The output, or its parts folder, is in a state this run must not touch (another spec's
    result, an interrupted run without --resume, a link): an input error (exit 2)."""


class OutputUnwritable(InputError, PermissionError):
    """The output's folder cannot be written: an input error (exit 2)."""


class OutputBusy(OutputRefused):
    """Another process is writing this output (it holds the lock)."""


# ---------------------------------------------------------------------------------------------
# one writer per output: an advisory lock beside it, held for the run's life
def lock_path(output: Path) -> Path:
    return output.with_name(output.name + LOCK_SUFFIX)


class OutputLock:
    """An exclusive `flock` on `<output>.lock`, which holds the owner's pid.

    The lock file is removed (under the lock) on release; a process that opened it before the
    removal notices that its file is no longer the one at the path and tries again."""

    def __init__(self, output: Path):
        self.output = Path(output)
        self.path = lock_path(self.output)
        self.fd = None

    def acquire(self) -> OutputLock:
        for _ in range(20):
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC,
                             0o644)
            except OSError as exc:
                if exc.errno == errno.ELOOP:
                    raise OutputRefused(f"{self.path} is a symbolic link; refusing to follow it "
                                          "(remove it)") from None
                raise OutputUnwritable(f"cannot write the output {self.output}: "
                                      f"{exc.strerror}") from None
            try:
                if not stat.S_ISREG(os.fstat(fd).st_mode):
                    raise OutputRefused(f"{self.path} is not a regular file; remove it")
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    pid = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
                    raise OutputBusy(f"{self.output} is being written by another sweep "
                                     f"(pid {pid}); "
                                     "wait for it to finish or stop it") from None
                st = os.fstat(fd)
                try:
                    cur = os.stat(self.path, follow_symlinks=False)
                except FileNotFoundError:
                    cur = None
                if cur is None or (cur.st_ino, cur.st_dev) != (st.st_ino, st.st_dev):
                    os.close(fd)  # the previous holder removed it after we opened it: again
                    continue
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
            except BaseException:
                try:
                    os.close(fd)
                except OSError:
                    pass
                raise
            self.fd = fd
            return self
        raise OutputBusy(f"{self.output}: could not take the lock {self.path}")

    def release(self) -> None:
        if self.fd is None:
            return
        try:
            os.unlink(self.path)
        except OSError:
            pass
        os.close(self.fd)
        self.fd = None


# ---------------------------------------------------------------------------------------------
# parts on disk: self-describing (chunk index, launch range, spec digest) and checksummed
def parts_dir(output: Path) -> Path:
    return output.with_name(output.name + PARTS_SUFFIX)


def _part_path(parts: Path, k: int) -> Path:
    return parts / f"chunk-{k:06d}.npz"


def _checksum(arrays: dict, meta: dict) -> str:
    h = hashlib.sha256(json.dumps({k: v for k, v in meta.items() if k != "sha256"},
                                  sort_keys=True).encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _atomic_write(directory: Path, final: Path, prefix: str, suffix: str, write) -> None:
    """Write through an unpredictable temporary file in `directory` (mkstemp: created new, never
    through a link), fsync it, and rename it onto `final`."""
    fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=directory)
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, final)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _write_part(parts: Path, k: int, lo: int, hi: int, digest: str, result: dict) -> None:
    arrays = {name: np.ascontiguousarray(v) for name, v in result.items()}
    meta = {"format": PART_FORMAT, "chunk": k, "lo": int(lo), "hi": int(hi), "spec_digest": digest}
    meta["sha256"] = _checksum(arrays, meta)
    _atomic_write(parts, _part_path(parts, k), f".chunk-{k:06d}.", ".tmp.npz",
                  lambda f: np.savez(f, __meta__=np.array(json.dumps(meta)), **arrays))


class PartInvalid(Exception):
    """A part file that cannot be used: unreadable, truncated, or not the chunk it names."""


class PartForeign(OutputRefused):
    """A part file made by another spec."""


def read_part(parts: Path, k: int, spec: Spec, lo: int, hi: int) -> dict:
    """Load and verify part k (chunk range lo..hi of this spec); returns {variable: array}."""
    path = _part_path(parts, k)
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["__meta__"]))
            arrays = {n: z[n] for n in z.files if n != "__meta__"}
    except Exception as exc:  # noqa: BLE001 - any failure to read a part makes it unusable
        raise PartInvalid(f"unreadable ({type(exc).__name__}: {str(exc)[:80]})") from None
    if not isinstance(meta, dict) or meta.get("format") != PART_FORMAT:
        raise PartInvalid("not a part of this format")
    if meta.get("spec_digest") != spec.digest:
        raise PartForeign(f"{path} was made by another spec; refusing to mix results (use "
                          "--force to start over)")
    if (meta.get("chunk"), meta.get("lo"), meta.get("hi")) != (k, lo, hi):
        raise PartInvalid(f"holds chunk {meta.get('chunk')} (launches {meta.get('lo')}.."
                          f"{meta.get('hi')}), expected chunk {k} (launches {lo}..{hi})")
    if meta.get("sha256") != _checksum(arrays, meta):
        raise PartInvalid("checksum mismatch")
    for name in spec.variables:
        a = arrays.get(name)
        if a is None or a.shape != (hi - lo,) or a.dtype != np.dtype(RESULT_VARIABLES[name][0]):
            raise PartInvalid(f"variable {name} missing or of the wrong shape or type")
    return arrays


def _partial_path(parts: Path, k: int) -> Path:
    return parts / f"partial-{k:06d}.npz"


def write_partial(parts: Path, k: int, lo: int, hi: int, digest: str, result: dict,
                  done: int) -> None:
    """Save the first `done` launches of chunk k (lo..hi), finished before an interruption."""
    arrays = {name: np.ascontiguousarray(v) for name, v in result.items()}
    meta = {"format": PART_FORMAT, "chunk": k, "lo": int(lo), "hi": int(hi), "done": int(done),
            "spec_digest": digest}
    meta["sha256"] = _checksum(arrays, meta)
    _atomic_write(parts, _partial_path(parts, k), f".partial-{k:06d}.", ".tmp.npz",
                  lambda f: np.savez(f, __meta__=np.array(json.dumps(meta)), **arrays))


def read_partials(parts: Path, spec: Spec, chunks: list, done: set, notice) -> dict:
    """Verified partial parts of chunks not done: {k: {variable: array of its first launches}}.
    Unusable ones are named and ignored (their launches are computed again)."""
    found = {}
    for p in sorted(parts.glob("partial-*.npz")):
        m = re.fullmatch(r"partial-(\d{6})\.npz", p.name)
        k = int(m.group(1)) if m else -1
        if not 0 <= k < len(chunks) or k in done:
            continue
        lo, hi, _ = chunks[k]
        try:
            with np.load(p, allow_pickle=False) as z:
                meta = json.loads(str(z["__meta__"]))
                arrays = {n: z[n] for n in z.files if n != "__meta__"}
            n = meta.get("done")
            ok = (isinstance(meta, dict) and meta.get("format") == PART_FORMAT
                  and meta.get("spec_digest") == spec.digest
                  and (meta.get("chunk"), meta.get("lo"), meta.get("hi")) == (k, lo, hi)
                  and isinstance(n, int) and 0 < n < hi - lo
                  and meta.get("sha256") == _checksum(arrays, meta)
                  and all(name in arrays and arrays[name].shape == (n,) and arrays[name].dtype
                          == np.dtype(RESULT_VARIABLES[name][0]) for name in spec.variables))
        except Exception:  # noqa: BLE001 - any failure to read a partial part makes it unusable
            ok = False
        if ok:
            found[k] = {name: arrays[name] for name in spec.variables}
        else:
            notice(f"{p} failed verification; computing its launches again")
    return found


def remove_partial(parts: Path, k: int) -> None:
    try:
        os.unlink(_partial_path(parts, k))
    except FileNotFoundError:
        pass


def _existing_digest(path: Path) -> str | None:
    import netCDF4

    try:
        with netCDF4.Dataset(path) as nc:
            return getattr(nc, "spec_digest", None)
    except OSError:
        return None


def _backend_hint(spec: Spec, digest) -> str:
    """' (it is this spec run with --backend X)' when `digest` is this spec's on another backend,
    else ''."""
    from .spec import BACKENDS, load_spec

    for backend in BACKENDS:
        if backend == spec.backend:
            continue
        try:
            other = load_spec(spec.source, text=spec.text, run={"backend": backend})
        except InputError:
            continue
        if digest is not None and other.digest == digest:
            return f" (it is this spec run with --backend {backend})"
    return ""


def output_is_current(spec: Spec) -> bool:
    """True when the spec's output file exists and was made by this same spec."""
    return spec.output.is_file() and _existing_digest(spec.output) == spec.digest


def check_output_path(out: Path) -> None:
    """Refuse output paths that cannot be a result file (before anything is written)."""
    out = Path(out)
    if not out.name.endswith(".nc") or out.name == ".nc":
        raise InputError(f"output {str(out)!r}: must be a file name ending in .nc")
    if out.is_dir():
        raise OutputRefused(f"output {out} is a directory; give a file name ending in .nc")
    parts = parts_dir(out)
    if parts.is_symlink() or (parts.exists() and not parts.is_dir()):
        raise OutputRefused(f"{parts} is not a directory a sweep made (a link or a file); "
                              "remove it")


def _clean_leftovers(out: Path, parts: Path) -> None:
    """Temporary files of earlier crashed runs (we hold the lock: nobody else is writing them)."""
    old_tmp = re.compile(r"^\." + re.escape(out.name) + r"\.(\d+\.tmp|tmp-.*)$")
    old_part_tmp = re.compile(r"^\.(chunk-.*\.tmp\.npz|partial-.*\.tmp\.npz|manifest.*\.tmp)$")
    for d, pattern in ((out.parent, old_tmp), (parts, old_part_tmp)):
        if not d.is_dir() or d.is_symlink():
            continue
        for entry in os.scandir(d):
            if not pattern.match(entry.name):
                continue
            try:
                if entry.is_dir(follow_symlinks=False):
                    shutil.rmtree(entry.path)
                else:
                    os.unlink(entry.path)
            except OSError:
                pass


def _write_manifest(parts: Path, spec: Spec, n_chunks: int) -> None:
    man = {"format": PART_FORMAT, "spec_digest": spec.digest, "version": __version__,
           "spec": spec.text, "shape": list(spec.shape), "chunk": spec.chunk,
           "n_chunks": n_chunks}
    _atomic_write(parts, parts / MANIFEST, ".manifest-", ".tmp",
                  lambda f: f.write(json.dumps(man).encode()))


def prepare_output(spec: Spec, *, resume: bool, force: bool, notice=None) -> tuple[Spec, Path, set]:
    """Check what is on disk (the caller holds the output's lock); returns (spec with the chunk
    plan to use, parts dir, chunks already done and verified). Refuses to mix specs."""
    notice = notice or _notice
    out = spec.output
    parts = parts_dir(out)
    if out.exists() and not force:
        if output_is_current(spec):
            raise UpToDate(f"{out} is up to date (made by this spec); --force recomputes it")
        hint = _backend_hint(spec, _existing_digest(out))
        raise OutputRefused(f"{out} exists, made by another spec{hint}; use --force to overwrite "
                            "it")
    _clean_leftovers(out, parts)
    if parts.exists():
        if force:
            shutil.rmtree(parts)
        elif not resume:
            raise OutputRefused(f"an interrupted sweep is in {parts}; use --resume to continue "
                                  "it or --force to start over")
        else:
            try:
                man = json.loads((parts / MANIFEST).read_text())
                if not isinstance(man, dict):
                    raise ValueError
            except (OSError, ValueError):
                raise OutputRefused(f"{parts} has no readable manifest; use --force") from None
            if man.get("spec_digest") != spec.digest:
                hint = _backend_hint(spec, man.get("spec_digest"))
                raise OutputRefused(f"{parts} belongs to a different spec{hint}; refusing to mix "
                                    "results (use --force to discard it)")
            if man.get("format") != PART_FORMAT or not isinstance(man.get("chunk"), int):
                raise OutputRefused(f"{parts} has no chunk plan (made by an older ballsurvey); "
                                      "use --force to start over")
            if list(man.get("shape", [])) != list(spec.shape):
                raise OutputRefused(f"{parts}: recorded grid {man.get('shape')} is not the "
                                      f"spec's {list(spec.shape)}; use --force")
            if man["chunk"] != spec.chunk:
                notice(f"resuming with the recorded chunk plan (chunk = {man['chunk']}); "
                       f"chunk = {spec.chunk} is ignored")
                spec = replace(spec, chunk=man["chunk"])
    parts.mkdir(exist_ok=True)
    if not (parts / MANIFEST).exists():
        _write_manifest(parts, spec, len(plan_chunks(spec.shape, spec.chunk)))
    chunks = plan_chunks(spec.shape, spec.chunk)
    done = set()
    for p in sorted(parts.glob("chunk-*.npz")):
        m = re.fullmatch(r"chunk-(\d{6})\.npz", p.name)
        k = int(m.group(1)) if m else -1
        if not 0 <= k < len(chunks):
            notice(f"ignoring {p}: not a chunk of this sweep's plan")
            continue
        lo, hi, _ = chunks[k]
        try:
            read_part(parts, k, spec, lo, hi)
        except PartInvalid as exc:
            notice(f"{p} failed verification ({exc}); computing it again")
            continue
        done.add(k)
    return spec, parts, done


def _notice(msg: str) -> None:
    print(f"ballsurvey sweep: {msg}", file=sys.stderr)


