"""The fit's statistics: the tracking noise from the track alone, tests of structure in the
residuals, the covariance from the Jacobian, and an angle's standard deviation."""
from __future__ import annotations

import math

import numpy as np

from .track import POSITION_PAIRS, Track

#: the noise estimate's relative spread: NOISE_SPREAD / sqrt(values) (third differences' MAD)
NOISE_SPREAD = 1.55


def noise_estimate(track: Track) -> tuple[float, int]:
    """The tracking noise of the positions (m, one coordinate), from the track alone: the
    median absolute third difference of consecutive samples, 1.4826 MAD / sqrt(20) (white
    noise of deviation s gives third differences of deviation sqrt(20) s; a smooth path adds
    its third derivative times dt^3, small at video rates). Returns (estimate, values used)."""
    d = np.concatenate([np.diff(getattr(track, k), 3)
                        for pair in POSITION_PAIRS for k in pair if getattr(track, k) is not None])
    return float(1.4826 * np.median(np.abs(d)) / math.sqrt(20.0)), int(d.size)


def residual_tests(res: dict) -> dict:
    """Structure in the position residuals (each channel in time order): the Wald-Wolfowitz
    runs test of their signs (z: below -4, far fewer runs than white noise makes) and the lag-1
    autocorrelation rho (z = rho sqrt(n))."""
    runs = mu = var = 0.0
    num = den = 0.0
    n_all = 0
    for r in res.values():
        pos = r > 0
        n1, n2 = int(pos.sum()), int((~pos).sum())
        n = n1 + n2
        if n1 == 0 or n2 == 0:
            continue
        runs += 1 + int(np.count_nonzero(pos[1:] != pos[:-1]))
        m = 2.0 * n1 * n2 / n + 1.0
        mu += m
        var += (m - 1.0) * (m - 2.0) / (n - 1.0)
        c = r - r.mean()
        num += float(np.dot(c[1:], c[:-1]))
        den += float(np.dot(c, c))
        n_all += n
    z_runs = (runs - mu) / math.sqrt(var) if var > 0 else 0.0
    rho = num / den if den > 0 else 0.0
    return {"runs_z": float(z_runs), "autocorrelation": float(rho),
            "autocorrelation_z": float(rho * math.sqrt(max(n_all, 1)))}


def _covariance(J: np.ndarray, s2: float):
    """Covariance s^2 (J^T J)^-1 by the SVD of J with its columns scaled to unit norm (no
    direction dropped: one the track does not fix comes out wide, not zero), its condition
    number, and the one-parameter floor sqrt(s^2 / |J_k|^2) below which no marginal sigma can
    lie."""
    norm = np.linalg.norm(J, axis=0)
    norm = np.where(norm > 0, norm, 1.0)
    _, sv, vt = np.linalg.svd(J / norm, full_matrices=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    sv = np.maximum(sv, sv[0] * 1e-15)
    cov = (vt.T / sv**2) @ vt / np.outer(norm, norm) * s2
    floor = np.sqrt(s2) / norm
    return cov, cond, floor


def _angle_err(f, q, cov, h=1e-6) -> float:
    """One standard deviation of an angle f(q) (deg) by linear propagation."""
    g = np.zeros(q.size)
    for k in range(q.size):
        dq = np.zeros(q.size)
        dq[k] = h * max(1.0, abs(q[k]))
        g[k] = ((f(q + dq) - f(q - dq) + 180.0) % 360.0 - 180.0) / (2 * dq[k])
    return float(math.sqrt(max(g @ cov @ g, 0.0)))
