"""The CPU's cycle counter inside numba code, for the benchmarks that count where a kernel's time
goes (`observation_cycles.py`, `quadrature_cycles.py`): `SOURCE` defines `rdtsc()` (LLVM's
readcyclecounter: the time-stamp counter, at its fixed rate) in the module it is put into."""

SOURCE = '''
from llvmlite import ir as _ir
from numba import types as _types
from numba.core import cgutils as _cgutils
from numba.extending import intrinsic as _intrinsic


@_intrinsic
def rdtsc(typingctx):
    def codegen(context, builder, sig, args):
        fnty = _ir.FunctionType(_ir.IntType(64), [])
        fn = _cgutils.get_or_insert_function(builder.module, fnty, "llvm.readcyclecounter")
        return builder.call(fn, [])
    return _types.int64(), codegen

'''


def patched(source: str, patches) -> str:
    """source with each (old, new) of patches replaced (old must be in it once) and `SOURCE` put
    after its imports (before the first line that starts with '@' or 'def')."""
    for old, new in patches:
        if source.count(old) != 1:
            raise SystemExit(f"the kernel's source has changed: {old.strip()[:40]!r} is not in "
                             "it once")
        source = source.replace(old, new)
    lines = source.split("\n")
    at = next(k for k, line in enumerate(lines) if line.startswith(("@", "def ", "class ")))
    return "\n".join(lines[:at] + SOURCE.split("\n") + lines[at:])
