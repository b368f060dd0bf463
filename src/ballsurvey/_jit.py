"""numba's `njit` for this package, with an on-disk cache that can never serve stale machine code.

The problem. numba's `cache=True` keeps compiled code in an index file per function and trusts it
while the *file that defines the function* is unchanged (numba >= 0.68 compares a hash of its
contents, older versions its mtime and size) and the function's own bytecode is the same. But a
jitted function that calls a jitted function from another file has the callee compiled *into* its
own object code: edit `physics/euler.py` and the cached ensemble kernel, the observer, the adaptive
stepper (all in other files) keep running the old equations, to the last digit, in every new
process. The generated RK kernel modules (`integrate/ensemble.py`) had the same problem one level
up: their file name came from the template alone.

The design. `SOURCE_DIGEST` is a SHA-256 over the contents (and relative paths) of every `.py`
file in `physics/`, `integrate/`, `classify/`, this file and `_version.py`, with the package, numba
and Python versions. Every jitted function of the package is in those directories, and they
import nothing from the rest of the package (both checked by tests/test_kernel_cache.py), so any
code a cached function can inline, or any module-level constant it can freeze, is covered by the
digest.

* `njit(cache=True, ...)` here is numba's `njit` with a cache whose freshness stamp is numba's own
  stamp *and* `SOURCE_DIGEST`: numba's locator still chooses the directory (next to the source, or
  under `NUMBA_CACHE_DIR`) and the file names, and numba's index check compares the whole stamp,
  so after any edit to any of those files every cached function of the package misses once,
  recompiles and overwrites its index. Nothing global is changed: `NUMBA_CACHE_DIR`, numba's
  locator list and other packages' functions are left alone.
* The generated kernel modules are named by a digest of their source text and `SOURCE_DIGEST`
  (`integrate/ensemble.py: make_kernels`), and they use this `njit` too, so a kernel module built
  from older physics is never imported.
* If the package sources cannot be read (e.g. a zip import), `SOURCE_DIGEST` is None and `njit`
  compiles without the on-disk cache: slower, never stale.
* If this numba's caching internals are not as expected (they are not public API), `njit` also
  compiles without the on-disk cache.

The cost: after an edit to any file in those directories every cached function of the package is
compiled again once, on first use; editing anything else (cli, sweep, store, plots) costs nothing.
Old generated kernel modules stay in the cache directory (small text files; delete at will).
"""
from __future__ import annotations

import hashlib
import math
import platform
from pathlib import Path

import numba as nb

from ._version import __version__

_PKG = Path(__file__).resolve().parent
#: directories (relative to the package) whose .py files are digested, with this file
DIGESTED_DIRS = ("physics", "integrate", "classify")


def digested_files(pkg: Path = _PKG) -> list[Path]:
    """The source files whose contents make SOURCE_DIGEST, in a fixed order."""
    files = [pkg / "_jit.py", pkg / "_version.py"]
    for d in DIGESTED_DIRS:
        files += sorted((pkg / d).rglob("*.py"))
    return files


def hash_files(h, files, root: Path) -> None:
    """Feed each file's path (relative to root) and bytes into the hash h (OSError propagates)."""
    for f in files:
        data = f.read_bytes()
        h.update(f.relative_to(root).as_posix().encode() + b"\0")
        h.update(len(data).to_bytes(8, "little") + data)


def source_digest(pkg: Path = _PKG) -> str | None:
    """SHA-256 (hex) of the digested sources and the versions; None when they cannot be read."""
    h = hashlib.sha256()
    for part in (__version__, nb.__version__, platform.python_version()):
        h.update(part.encode() + b"\0")
    try:
        hash_files(h, digested_files(pkg), pkg)
    except OSError:
        return None
    return h.hexdigest()


SOURCE_DIGEST = source_digest()


class _StampedLocator:
    """Wraps the numba locator chosen for a function; its stamp gains SOURCE_DIGEST."""

    def __init__(self, inner):
        self._inner = inner

    def get_source_stamp(self):
        return ("ballsurvey", SOURCE_DIGEST, self._inner.get_source_stamp())

    def __getattr__(self, name):  # get_cache_path, ensure_cache_path, get_disambiguator, ...
        return getattr(self._inner, name)


def _make_cache_class():
    try:
        from numba.core.caching import CompileResultCacheImpl, FunctionCache
    except ImportError:
        return None

    class _Impl(CompileResultCacheImpl):
        def __init__(self, py_func):
            super().__init__(py_func)
            self._locator = _StampedLocator(self._locator)

    class PackageFunctionCache(FunctionCache):
        """numba's FunctionCache, fresh only for the same SOURCE_DIGEST (module docstring)."""

        _impl_class = _Impl

    return PackageFunctionCache


_CACHE_CLASS = _make_cache_class()


def caching_available() -> bool:
    return SOURCE_DIGEST is not None and _CACHE_CLASS is not None


def njit(*, cache: bool = False, **options):
    """Decorator like `numba.njit(**options)`; `cache=True` uses the digest-stamped disk cache."""
    base = nb.njit(**options)

    def decorate(py_func):
        disp = base(py_func)
        if cache and caching_available():
            try:
                # what Dispatcher.enable_caching does, with our cache class
                disp._cache = _CACHE_CLASS(py_func)
            except (RuntimeError, AttributeError, OSError):  # no usable locator: in memory
                pass
        return disp

    return decorate


@nb.extending.intrinsic
def _llvm_sqrt(typingctx, x):
    sig = nb.types.float64(nb.types.float64)

    def codegen(context, builder, signature, args):
        fn = builder.module.declare_intrinsic("llvm.sqrt", [args[0].type])
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True, nogil=True, error_model="numpy")
def sqrt(x):
    """math.sqrt of a float64 as LLVM's sqrt instruction: the same correctly rounded value (NaN
    for x < 0, as the processor's square root gives it), but no libm call that may set errno,
    which LLVM must keep as a call wherever it cannot prove x >= 0, and which stops a loop over
    launches from vectorising. On a GPU (`integrate/cuda.py: device_twin`) it is math.sqrt, the
    same correctly rounded value."""
    return _llvm_sqrt(float(x))


sqrt.device_form = math.sqrt


@nb.extending.intrinsic
def fetch_add(typingctx, counter, delta):
    """counter[0] += delta as one atomic step (LLVM's atomicrmw); returns the value before. For
    threads that share out work: each takes the next item whichever of them is free first."""
    if not (isinstance(counter, nb.types.Array) and counter.dtype == nb.types.int64
            and isinstance(delta, nb.types.Integer)):
        return None
    sig = nb.types.int64(counter, delta)

    def codegen(context, builder, signature, args):
        arr = context.make_array(signature.args[0])(context, builder, args[0])
        ptr = builder.gep(arr.data, [context.get_constant(nb.types.intp, 0)])
        val = context.cast(builder, args[1], signature.args[1], nb.types.int64)
        return builder.atomic_rmw("add", ptr, val, "seq_cst")

    return sig, codegen


@nb.extending.intrinsic
def borrow(typingctx, arr):
    """A view of the array arr that owns nothing (no meminfo): passing it on to functions
    inlined in numba's IR costs no reference-count update, an atomic add and a call, at each
    inlined call (the quadrature kernel's launches: 6 % of their time). The caller must keep
    arr itself alive while the view is in use (`alive`)."""
    if not isinstance(arr, nb.types.Array):
        return None
    sig = arr(arr)

    def codegen(context, builder, signature, args):
        src = context.make_array(signature.args[0])(context, builder, args[0])
        out = context.make_array(signature.return_type)(context, builder)
        for field in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(out, field, getattr(src, field))
        out.meminfo = nb.core.cgutils.get_null_value(out.meminfo.type)
        out.parent = nb.core.cgutils.get_null_value(out.parent.type)
        return out._getvalue()

    return sig, codegen


@nb.extending.intrinsic
def alive(typingctx, arrays):
    """Nothing, but a use of the tuple `arrays`: numba releases an array after its last use, so
    its owner stays alive up to here while views of it (`borrow`) are used before."""
    if not isinstance(arrays, nb.types.BaseTuple):
        return None
    return nb.types.none(arrays), lambda context, builder, signature, args: None
