"""Provenance of a map: the global attributes (spec text and digest, ball, thresholds, step used,
version and git commit, history)."""
from __future__ import annotations

import datetime as _dt
import subprocess
from pathlib import Path

from .. import __version__
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
