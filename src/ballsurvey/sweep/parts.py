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

from .._version import __version__
from ..limits import InputError, RunError
from ..schema import RESULT_VARIABLES
from .plan import plan_chunks
from .provenance import code_digest
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


def _existing_digests(path: Path) -> tuple:
    """(spec digest, code digest, source) recorded in a map; None for what it lacks."""
    import netCDF4

    from ..store import netcdf_lock

    try:
        with netcdf_lock(direct=True), netCDF4.Dataset(path) as nc:
            return tuple(getattr(nc, k, None) for k in ("spec_digest", "code_digest", "source"))
    except OSError:
        return None, None, None


def _existing_digest(path: Path) -> str | None:
    return _existing_digests(path)[0]


def _code_words(code, version=None) -> str:
    """'ballsurvey 0.1.0, code 1a2b3c4d5e6f' for a recorded code digest (and version)."""
    if not isinstance(code, str) or not code:
        return f"{version or 'an older ballsurvey'}, no code digest recorded"
    return f"{version or 'ballsurvey'}, code {code[:12]}"


def _this_code() -> str:
    return _code_words(code_digest(), f"ballsurvey {__version__}")


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
    """True when the spec's output file exists and was made by this same spec and this same code
    (`provenance.code_digest`)."""
    if not spec.output.is_file():
        return False
    digest, code, _ = _existing_digests(spec.output)
    return digest == spec.digest and code == code_digest()


def _resumable(spec: Spec) -> bool:
    """Saved parts beside the output that this spec and this code can resume (so a printed
    --force --resume runs as printed)."""
    parts = parts_dir(spec.output)
    if not (parts / MANIFEST).is_file():
        return False
    try:
        _check_manifest(parts, spec)
    except OutputRefused:
        return False
    return True


def existing_output(spec: Spec, *, force: bool) -> None:
    """What an existing output means for a run: nothing when there is none or with --force;
    UpToDate when this spec and this code made it; else OutputRefused saying why."""
    out = spec.output
    if force or not (out.exists() or out.is_symlink()):
        return
    digest, code, source = _existing_digests(out)
    if digest == spec.digest and code == code_digest():
        raise UpToDate(f"{out} is up to date (made by this spec and this code); --force "
                       "recomputes it")
    keep = " (--force --resume keeps the saved parts)" if _resumable(spec) else ""
    if digest is None:
        raise OutputRefused(f"{out} exists and is not a map written by a sweep (no spec digest "
                            f"in it, or not netCDF); use --force to overwrite it{keep}")
    if code != code_digest():  # its spec digest may be of another scheme: not compared
        version = source.split(" (")[0] if isinstance(source, str) else None
        which = "this spec" if digest == spec.digest else "a spec"
        raise OutputRefused(f"{out} was made by {which} with other code "
                            f"({_code_words(code, version)}; this is {_this_code()}): its results "
                            f"may differ from this code's; --force recomputes it{keep}")
    hint = _backend_hint(spec, digest)
    raise OutputRefused(f"{out} exists, made by another spec{hint}; use --force to overwrite "
                        f"it{keep}")


def check_output_path(out: Path) -> None:
    """Refuse output paths that cannot be a result file (before anything is written)."""
    out = Path(out)
    if not out.name.endswith(".nc") or out.name == ".nc":
        raise InputError(f"output {str(out)!r}: must be a file name ending in .nc")
    if out.is_dir():
        raise OutputRefused(f"output {out} is a directory; give a file name ending in .nc")
    ancestors = [*Path(os.path.abspath(out)).parents, *out.resolve().parents]  # links too
    for d in ancestors:  # a sweep's own folders: removed when it ends
        if d.name.endswith(".nc" + PARTS_SUFFIX) or re.match(r"^\..+\.nc\.tmp-", d.name):
            raise OutputRefused(f"output {out} is inside {d}, a sweep's working folder that is "
                                "removed when that sweep ends; write it elsewhere")
    parts = parts_dir(out)
    if parts.is_symlink() or (parts.exists() and not parts.is_dir()):
        raise OutputRefused(f"{parts} is not a directory a sweep made (a link or a file); "
                              "remove it")


def _clean_leftovers(out: Path, parts: Path) -> None:
    """Temporary files of earlier crashed runs (we hold the lock: nobody else is writing them).
    A temporary folder's suffix has no dot, so a neighbouring output's (`a.nc.tmp-b.nc` beside
    `a.nc`) is not taken for this output's."""
    old_tmp = re.compile(r"^\." + re.escape(out.name) + r"\.(\d+\.tmp|tmp-[^.]*)$")
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
           "code_digest": code_digest(), "spec": spec.text, "shape": list(spec.shape),
           "chunk": spec.chunk,
           "n_chunks": n_chunks}
    _atomic_write(parts, parts / MANIFEST, ".manifest-", ".tmp",
                  lambda f: f.write(json.dumps(man).encode()))


def _discard_parts(parts: Path, notice) -> None:
    n = len(list(parts.glob("chunk-*.npz"))) + len(list(parts.glob("partial-*.npz")))
    shutil.rmtree(parts)
    if n:
        notice(f"discarded {n} saved part{'s' if n != 1 else ''} in {parts} (--force without "
               "--resume starts over)")


def _check_manifest(parts: Path, spec: Spec) -> dict:
    """The parts' manifest when they can be resumed by this spec and this code; else
    OutputRefused saying why and what to do."""
    discard = "--force without --resume discards them and starts over"
    try:
        man = json.loads((parts / MANIFEST).read_text())
        if not isinstance(man, dict):
            raise ValueError
    except (OSError, ValueError):
        raise OutputRefused(f"{parts} has no readable manifest; {discard}") from None
    if man.get("code_digest") != code_digest():  # first: another code may digest specs otherwise
        version = man.get("version")
        was = _code_words(man.get("code_digest"), version and f"ballsurvey {version}")
        raise OutputRefused(
            f"{parts} was saved by other code ({was}; "
            f"this is {_this_code()}): its launches may differ from this code's; refusing to mix "
            f"results ({discard})")
    if man.get("spec_digest") != spec.digest:
        hint = _backend_hint(spec, man.get("spec_digest"))
        raise OutputRefused(f"{parts} belongs to a different spec{hint}; refusing to mix "
                            f"results ({discard})")
    if man.get("format") != PART_FORMAT or not isinstance(man.get("chunk"), int):
        raise OutputRefused(f"{parts} has no chunk plan (made by an older ballsurvey); {discard}")
    if list(man.get("shape", [])) != list(spec.shape):
        raise OutputRefused(f"{parts}: recorded grid {man.get('shape')} is not the "
                            f"spec's {list(spec.shape)}; {discard}")
    return man


def tidy_finished(spec: Spec, notice=None) -> None:
    """The output is up to date: remove what a run that ended between writing it and cleaning
    up left (its temporary folder, its parts), unless another sweep holds the output's lock."""
    notice = notice or _notice
    lock = OutputLock(spec.output)
    try:
        lock.acquire()
    except (OutputRefused, OutputUnwritable):
        return
    try:
        _tidy_finished(spec, notice)
    finally:
        lock.release()


def _tidy_finished(spec: Spec, notice) -> None:
    parts = parts_dir(spec.output)
    _clean_leftovers(spec.output, parts)
    if parts.is_dir() and not parts.is_symlink():
        try:
            _check_manifest(parts, spec)
        except OutputRefused:
            return  # not this run's: left alone
        shutil.rmtree(parts, ignore_errors=True)
        notice(f"removed {parts}, left by a run that ended after writing {spec.output}")


def prepare_output(spec: Spec, *, resume: bool, force: bool, notice=None) -> tuple[Spec, Path, set]:
    """Check what is on disk (the caller holds the output's lock); returns (spec with the chunk
    plan to use, parts dir, chunks already done and verified). Refuses to mix specs or code.

    resume: continue from the saved parts (this spec's and this code's, else refused); force:
    overwrite an existing output. Both: continue from the parts and overwrite the output at the
    end. force alone discards saved parts (and says so)."""
    notice = notice or _notice
    out = spec.output
    parts = parts_dir(out)
    try:
        existing_output(spec, force=force)
    except UpToDate:
        _tidy_finished(spec, notice)
        raise
    _clean_leftovers(out, parts)
    if parts.is_dir() and not parts.is_symlink() and not any(parts.iterdir()):
        parts.rmdir()  # made by a run killed before it wrote anything in it: nothing to resume
    if parts.exists():
        if resume:
            man = _check_manifest(parts, spec)
            if man["chunk"] != spec.chunk:
                notice(f"resuming with the recorded chunk plan (chunk = {man['chunk']}); "
                       f"chunk = {spec.chunk} is ignored")
                spec = replace(spec, chunk=man["chunk"])
        elif force:
            _discard_parts(parts, notice)
        else:
            raise OutputRefused(f"an interrupted sweep is in {parts}; use --resume to continue "
                                  "it or --force to start over")
    parts.mkdir(exist_ok=True)
    if not (parts / MANIFEST).exists():
        try:
            _write_manifest(parts, spec, len(plan_chunks(spec.shape, spec.chunk)))
        except OSError as exc:
            raise RunError(f"cannot write {parts / MANIFEST}: {exc.strerror or exc}; nothing "
                           "was computed") from None
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


