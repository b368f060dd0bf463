"""Sweeps: spec parsing and validation (`spec`), chunked execution and storage (`engine`)."""
from .engine import compute_chunk, plan_chunks, run_sweep
from .spec import Spec, SpecError, load_spec

__all__ = ["Spec", "SpecError", "load_spec", "run_sweep", "compute_chunk", "plan_chunks"]
