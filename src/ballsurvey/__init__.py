"""ballsurvey: maps how a biased ball rolls (Wheatland, Cross et al., Am. J. Phys. 88, 465 (2020)).

Public API: `Ball`, `simulate`, `Thresholds`, `LABELS`.
"""
__version__ = "0.1.0"

from .ball import Ball  # noqa: E402
from .classify.labels import LABELS, Thresholds  # noqa: E402
from .simulate import simulate  # noqa: E402

__all__ = ["Ball", "simulate", "Thresholds", "LABELS", "__version__"]
