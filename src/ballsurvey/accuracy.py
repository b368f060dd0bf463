"""Work-precision report: error against run time for fixed-step RK4 and the adaptive pair.

For each case (the paper's launches and the extreme ones) a reference is computed in the same run
with the adaptive pair at tight tolerance in the Euler form, and confirmed by the fixed-frame form
(their disagreement is printed as the reference's own uncertainty). Each setting is then timed on
the one launch (serial kernel) and compared with it: final position error (m), final theta error
(rad), largest drift of energy (relative), Jellett and Routh (SI), wall time (s), label.

Also the label agreement over a small map against dt (and tolerance): the coarsest dt and loosest
tolerance at which every label still agrees with the reference labels.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .ball import Ball
from .classify.labels import LABELS, SHAPES, Thresholds, fold_deg
from .classify.observer import N_OBS
from .compose import OBSERVER, classify, run_launches
from .integrate import ensemble
from .integrate.adaptive import integrate_adaptive
from .integrate.lanes import integrate_lanes
from .physics.fast import S_TH, S_X, S_Y
from .units import StepPlan, fields_to_si, launch_state

RK4_DTS = (1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5)
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10)
REF_RTOL = 1e-12


@dataclass(frozen=True)
class Case:
    name: str
    theta0_deg: float
    thetadot0: float
    chidot0: float
    phidot0: float
    T: float = 20.0
    ball: Ball = Ball()
    note: str = ""


def cases() -> list[Case]:
    from .paper import FIGURES

    paper = Ball.paper()

    def fig(name, **kw):
        f = FIGURES[name]
        return Case(name, f["theta0_deg"], f["thetadot0"], f["chidot0"], f["phidot0"], **kw)

    return [
        fig("fig7", note="paper: nearly straight"),
        fig("fig9a", note="paper: approximately circular"),
        fig("fig12a", note="paper: square"),
        fig("fig12b", note="paper: triangle"),
        Case("near_vertical", 89.2, 0.0, 2.0, -3.0, T=5.0, note="theta0 within 1 deg of 90"),
        Case("high_spin", 10.0, 0.0, 200.0, -3.0, T=2.0, note="|chidot0| = 200 rad/s"),
        Case("nearly_symmetric", 20.0, 0.0, 4.0, -3.0,
             ball=replace(paper, c=1e-5, cut_height=0.0), note="c = 1e-5 m (c -> 0)"),
        Case("heavy_bias", 10.0, 0.0, 4.0, -3.0, T=10.0,
             ball=replace(paper, c=0.5 * paper.a, cut_height=0.0), note="c = a/2"),
        replace(fig("fig12a"), name="long_run", T=200.0, note="Fig. 12a for T = 200 s"),
    ]


def _launch(case: Case):
    b = case.ball
    tu = b.time_unit
    y0 = launch_state(case.theta0_deg, case.thetadot0, case.chidot0, case.phidot0, tu)
    return y0, b.nondim_params()[:, None], tu, b


def _summary(case, res, wall, ref_end):
    y0, p, tu, b = _launch(case)
    f = fields_to_si(classify(res, b.flat_face_theta_rad), b.a, tu, b.M)
    y_end = res.y_end
    dpos = math.hypot(y_end[S_X, 0] - ref_end[S_X], y_end[S_Y, 0] - ref_end[S_Y]) * b.a
    dth = abs(y_end[S_TH, 0] - ref_end[S_TH])
    return dict(pos_err_m=dpos, theta_err_rad=dth, energy_drift=float(f["energy_drift"][0]),
                jellett_drift=float(f["jellett_drift"][0]),
                routh_drift=float(f["routh_drift"][0]), wall_s=wall,
                label=LABELS[int(f["label"][0])])


def _adaptive(y0, p, T_nd, rtol, atol, **kw):
    return integrate_adaptive(y0, p, T_nd, rtol, atol, observer=OBSERVER, n_slots=N_OBS,
                              parallel=False, **kw)


def best_of(fn, repeats=1):
    """(fn's last result, its best wall time in s over `repeats` calls)."""
    best = math.inf
    out = None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return out, best


def reference(case: Case):
    """(Euler-form reference final state, fixed-frame final state, their position gap in m)."""
    y0, p, tu, b = _launch(case)
    ye = _adaptive(y0, p, case.T / tu, REF_RTOL, 1e-14).y_end
    yf = _adaptive(y0, p, case.T / tu, REF_RTOL, 1e-14, fixed_frame=True).y_end
    gap = math.hypot(ye[S_X, 0] - yf[S_X, 0], ye[S_Y, 0] - yf[S_Y, 0]) * b.a
    ok = np.isfinite(ye[S_X, 0])
    return (ye[:, 0] if ok else yf[:, 0]), yf[:, 0], gap


def work_precision(case: Case, dts=RK4_DTS, rtols=RTOLS) -> list[dict]:
    y0, p, tu, b = _launch(case)
    ref, _, gap = reference(case)
    rows = []
    for dt in dts:
        plan = StepPlan(case.T, dt, tu)
        if plan.n_steps > 5_000_000:
            continue

        def run(plan=plan):
            return ensemble.integrate(y0, p, plan.dt_nd, plan.n_steps, observer=OBSERVER,
                                      n_slots=N_OBS, block=1, observe_every=1, parallel=False)

        res, wall = best_of(run)
        rows.append(dict(case=case.name, method="rk4", setting=dt,
                         **_summary(case, res, wall, ref), ref_gap_m=gap))
    for rtol in rtols:
        def run(rtol=rtol):
            return _adaptive(y0, p, case.T / tu, rtol, rtol * 1e-3)

        res, wall = best_of(run)
        rows.append(dict(case=case.name, method="dopri5", setting=rtol,
                         **_summary(case, res, wall, ref), ref_gap_m=gap))
    return rows


def label_agreement(dts=(2e-3, 1e-3, 5e-4, 2e-4, 1e-4), rtols=(1e-4, 1e-6, 1e-8), n=8,
                    T=20.0) -> dict:
    """Labels of an n x n (theta0, chidot0) map at phidot0 = -3 rad/s against the reference
    (adaptive, rtol 1e-11). Returns {('rk4', dt) | ('dopri5', rtol): fraction agreeing}."""
    b = Ball.paper()
    tu, p = b.time_unit, b.nondim_params()
    th, cd = np.meshgrid(np.linspace(-10, 30, n), np.linspace(1, 12, n), indexing="ij")
    y0 = launch_state(th.ravel(), 0.0, cd.ravel(), -3.0, tu)
    params = np.repeat(p[:, None], n * n, 1)

    def labels(res):
        return classify(res, b.flat_face_theta_rad, Thresholds())["label"]

    ref = labels(run_launches(y0, params, StepPlan(T, 1e-4, tu), "dopri5", rtol=1e-11,
                              atol=1e-14))
    out = {}
    for dt in dts:
        out[("rk4", dt)] = float(np.mean(labels(run_launches(y0, params,
                                                             StepPlan(T, dt, tu))) == ref))
    for rtol in rtols:
        out[("dopri5", rtol)] = float(np.mean(labels(run_launches(
            y0, params, StepPlan(T, 1e-4, tu), "dopri5", rtol=rtol, atol=rtol * 1e-3)) == ref))
    return out


def quadrature_check(n=60, seed=3, T=20.0, dt=1e-4) -> dict:
    """Quadrature (no time stepping) against full integration and against the period mode on
    random launches: the largest disagreement in theta period (relative), turn per cycle (deg)
    and theta_max (deg). Launches that are steady, reach |theta| > 88 deg or get a status are
    skipped (the quadrature needs the Euler chart)."""
    from .quadrature import cycle_by_quadrature

    b = Ball.paper()
    tu, p = b.time_unit, b.nondim_params()
    rng = np.random.default_rng(seed)
    th = rng.uniform(-20, 60, n)
    td, cd, pd = rng.uniform(-2, 2, n), rng.uniform(-12, 12, n), rng.uniform(-8, 8, n)
    y0 = launch_state(th, td, cd, pd, tu)
    params = np.repeat(p[:, None], n, 1)
    plan = StepPlan(T, dt, tu)
    runs = {name: fields_to_si(classify(run_launches(y0, params, plan, cycles=cycles),
                                        b.flat_face_theta_rad), b.a, tu, b.M)
            for name, cycles in (("full", 0), ("period", 2))}
    worst = {k: {"period_rel": 0.0, "turn_deg": 0.0, "theta_max_deg": 0.0} for k in runs}
    used = 0
    for i in range(n):
        q = cycle_by_quadrature(math.radians(th[i]), td[i] * tu, cd[i] * tu, pd[i] * tu, p)
        if q is None or math.degrees(q.theta_max) > 88:
            continue
        qs = q.si(b)
        if any(LABELS[r["label"][i]] in ("inaccurate", "blew_up", "unresolved", "singular")
               or r["formulation"][i] for r in runs.values()):
            continue
        used += 1
        for k, r in runs.items():
            w = worst[k]
            w["period_rel"] = max(w["period_rel"],
                                  abs(r["theta_period_s"][i] / qs["theta_period_s"] - 1))
            dturn = fold_deg(r["turn_per_cycle_deg"][i] - qs["turn_per_cycle_deg"])
            w["turn_deg"] = max(w["turn_deg"], abs(dturn))
            w["theta_max_deg"] = max(w["theta_max_deg"],
                                     abs(r["theta_max_deg"][i] - qs["theta_max_deg"]))
    return {"launches": used, **worst}


#: the map settings near_vertical_check measures: name -> run_launches keywords
NEAR_VERTICAL_RUNS = {
    "rk4 full": dict(method="rk4", dt=1e-4, cycles=0),
    "rk4 period": dict(method="rk4", dt=1e-4, cycles=2),
    "dop853 period": dict(method="dop853", dt=1e-3, cycles=2),
    "quadrature period": dict(method="quadrature", dt=1e-3, cycles=2),
}


def near_vertical_check(n=40, seed=5, T=20.0) -> dict:
    """Per-cycle figures of launches whose tilt comes within a few degrees of the vertical
    (theta0 from 80 to 89.9 deg, spin and precession as the paper's squares), where the Euler
    chart is left and the fixed-frame form takes over, against the quadrature (which holds up
    to a hair of 90 deg): for each map setting of NEAR_VERTICAL_RUNS, the largest error in turn
    per cycle (deg) and in n_sides, over the launches the quadrature resolves and every run
    labels with a shape; and on every launch, whether each setting's label is full RK4's
    (`same_label`, of `n`). quadrature_check leaves these launches out."""
    from .quadrature import cycle_by_quadrature

    b = Ball.paper()
    tu, p = b.time_unit, b.nondim_params()
    rng = np.random.default_rng(seed)
    th = rng.uniform(80.0, 89.9, n)
    td, cd, pd = np.zeros(n), rng.uniform(2.0, 6.0, n), rng.uniform(-4.0, -2.0, n)
    y0 = launch_state(th, td, cd, pd, tu)
    params = np.repeat(p[:, None], n, 1)
    runs = {}
    for name, kw in NEAR_VERTICAL_RUNS.items():
        res = run_launches(y0, params, StepPlan(T, kw["dt"], tu), kw["method"], rtol=1e-9,
                           cycles=kw["cycles"])
        runs[name] = fields_to_si(classify(res, b.flat_face_theta_rad), b.a, tu, b.M)
    worst = {k: {"turn_deg": 0.0, "n_sides": 0.0, "same_n": 0,
                 "same_label": int(np.sum(r["label"] == runs["rk4 full"]["label"]))}
             for k, r in runs.items()}
    used = fixed_frame = 0
    for i in range(n):
        q = cycle_by_quadrature(math.radians(th[i]), td[i] * tu, cd[i] * tu, pd[i] * tu, p)
        if q is None or any(LABELS[r["label"][i]] not in SHAPES for r in runs.values()):
            continue
        qs = q.si(b)
        used += 1
        fixed_frame += bool(runs["rk4 full"]["formulation"][i])
        n_q = 360.0 / abs(qs["turn_per_cycle_deg"])
        for k, r in runs.items():
            dturn = fold_deg(r["turn_per_cycle_deg"][i] - qs["turn_per_cycle_deg"])
            worst[k]["turn_deg"] = max(worst[k]["turn_deg"], abs(dturn))
            worst[k]["n_sides"] = max(worst[k]["n_sides"], abs(r["n_sides"][i] - n_q))
            # the n-region (round n: triangle, square, ...) the launch is put in, where the
            # quadrature's n is not within 0.02 of a region's edge
            worst[k]["same_n"] += (abs(n_q - math.floor(n_q) - 0.5) < 0.02
                                   or round(r["n_sides"][i]) == round(n_q))
    return {"launches": used, "fixed_frame": fixed_frame, "n": n, **worst}


def square_launches(n: int = 256, seed: int = 0, T: float = 20.0):
    """The ensemble work-precision launches: n launches around Fig. 12a's square (theta0 within
    0.5 deg, chidot0 within 0.05 rad/s of it, phidot0 = -3 rad/s), seeded; these pass within a few
    degrees of the vertical. Returns (fast states, params, T non-dimensional, ball)."""
    from .paper import FIGURES

    ball = Ball.paper()
    tu = ball.time_unit
    f = FIGURES["fig12a"]
    rng = np.random.default_rng(seed)
    th = f["theta0_deg"] + rng.uniform(-0.5, 0.5, n)
    chd = f["chidot0"] + rng.uniform(-0.05, 0.05, n)
    y0 = np.concatenate([launch_state(t, 0.0, c, f["phidot0"], tu) for t, c in zip(th, chd)], 1)
    return y0, np.repeat(ball.nondim_params()[:, None], n, 1), T / tu, ball


def ensemble_reference(y0, params, T_nd):
    """Final (x, y) of each launch, non-dimensional, from DOP853 in the SIMD-lane kernel at rtol
    1e-13, and its largest gap (non-dimensional) from an independent reference: the scalar
    Dormand-Prince 5(4) at rtol 1e-12, also in the fixed frame."""
    ref = integrate_lanes(y0, params, T_nd, 1e-13, 1e-16)
    other = integrate_adaptive(y0, params, T_nd, 1e-12, 1e-15, observer=OBSERVER, n_slots=N_OBS,
                               fixed_frame=True)
    xy = ref.traj[:2]
    gap = np.hypot(*(xy - other.y_end[:2])).max()
    return xy, gap


def ensemble_work_precision(n: int = 256, repeats: int = 3, emit=print,
                            rtols=(1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11),
                            dts=(1e-3, 5e-4, 2e-4, 1e-4, 5e-5),
                            dopri5_rtols=(1e-6, 1e-8, 1e-10)) -> list[dict]:
    """Work-precision over an ensemble: n full launches around the square (`square_launches`),
    final position error against `ensemble_reference` (median and largest, m) and launches per
    second on all threads, for DOP853 in the SIMD-lane kernel, the scalar adaptive Dormand-Prince
    5(4) (fixed frame) and fixed-step RK4 in the ensemble kernel (Euler form, with its observer)."""
    y0, p, T, ball = square_launches(n)
    xy_ref, gap = ensemble_reference(y0, p, T)
    rows = []

    def row(method, setting, run):
        res, best = best_of(run, repeats)
        xy = res.traj[:2] if method == "dop853" else res.y_end[:2]
        err = np.hypot(*(xy - xy_ref)) * ball.a
        err = np.where(np.isfinite(err), err, np.inf)
        rows.append(dict(method=method, setting=setting, median_err_m=float(np.median(err)),
                         max_err_m=float(err.max()), launches_per_s=n / best,
                         steps=float(np.mean(res.n_steps))))

    # compile (or load) every kernel outside the timings
    integrate_lanes(y0[:, :2], p[:, :2], 0.01, 1e-6, 1e-9)
    integrate_adaptive(y0[:, :2], p[:, :2], 0.01, 1e-6, 1e-9, observer=OBSERVER, n_slots=N_OBS,
                       fixed_frame=True)
    ensemble.integrate(y0[:, :2], p[:, :2], 1e-3, 4, observer=OBSERVER, n_slots=N_OBS,
                       observe_every=4)
    for rtol in rtols:
        row("dop853", rtol, lambda rtol=rtol: integrate_lanes(y0, p, T, rtol, rtol * 1e-3))
    for rtol in dopri5_rtols:
        row("dopri5", rtol, lambda rtol=rtol: integrate_adaptive(
            y0, p, T, rtol, rtol * 1e-3, observer=OBSERVER, n_slots=N_OBS, fixed_frame=True))
    tu = ball.time_unit
    for dt in dts:
        plan = StepPlan(T * tu, dt, tu)
        row("rk4", dt, lambda plan=plan: ensemble.integrate(
            y0, p, plan.dt_nd, plan.n_steps, observer=OBSERVER, n_slots=N_OBS, observe_every=4))
    emit(f"ensemble work-precision: {n} launches around the square (Fig. 12a +- 0.5 deg, "
         f"+- 0.05 rad/s), T = {T * tu:g} s, {_threads()} threads, best of {repeats}")
    emit(f"  reference: DOP853 rtol 1e-13 (fixed frame); independent check, dopri5 rtol 1e-12: "
         f"largest gap {gap * ball.a:.1e} m")
    emit(f"  {'method':<8}{'setting':>9}{'median err (m)':>16}{'max err (m)':>13}"
         f"{'launches/s':>12}{'steps':>9}")
    for r in rows:
        emit(f"  {r['method']:<8}{r['setting']:>9.0e}{r['median_err_m']:>16.2e}"
             f"{r['max_err_m']:>13.2e}{r['launches_per_s']:>12.0f}{r['steps']:>9.0f}")
    return rows


def _threads() -> int:
    import numba

    return numba.get_num_threads()


def run_accuracy(out_dir="results/accuracy", quick=False, emit=print,
                 fig_format: str = "png") -> dict:
    """The whole report: table (printed), netCDF file and log-log plot (as `fig_format`: png,
    pdf or svg) in out_dir."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    import xarray as xr

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cs = cases()
    if quick:
        cs = [c for c in cs if c.name in ("fig12a", "high_spin", "near_vertical")]
        cs = [replace(c, T=min(c.T, 5.0)) for c in cs]
    # warm the kernels (compilation is not part of any timing)
    warm = replace(cs[0], T=0.01)
    work_precision(warm, dts=(1e-3,), rtols=(1e-6,))
    rows = []
    for c in cs:
        rows += work_precision(c, dts=RK4_DTS[2:6] if quick else RK4_DTS,
                               rtols=RTOLS[1:3] if quick else RTOLS)
    emit(f"{'case':<17}{'method':<8}{'setting':>9}{'pos err (m)':>13}{'theta err':>11}"
         f"{'dE/E':>10}{'dJ':>10}{'dR':>10}{'time (s)':>10}  label")
    for r in rows:
        emit(f"{r['case']:<17}{r['method']:<8}{r['setting']:>9.0e}{r['pos_err_m']:>13.2e}"
             f"{r['theta_err_rad']:>11.2e}{r['energy_drift']:>10.1e}{r['jellett_drift']:>10.1e}"
             f"{r['routh_drift']:>10.1e}{r['wall_s']:>10.4f}  {r['label']}")
    gaps = {r["case"]: r["ref_gap_m"] for r in rows}
    emit("reference (dopri5, rtol 1e-12) vs fixed-frame form, final position gap (m): " +
         ", ".join(f"{k} {v:.1e}" for k, v in gaps.items()))
    ens = ensemble_work_precision(n=32 if quick else 256, repeats=1 if quick else 3, emit=emit,
                                  **(dict(rtols=(1e-6, 1e-9), dts=(2e-4,), dopri5_rtols=(1e-8,))
                                     if quick else {}))
    agree = label_agreement(n=5 if quick else 8, T=10.0 if quick else 20.0,
                            dts=(1e-3, 5e-4, 2e-4) if quick else (2e-3, 1e-3, 5e-4, 2e-4, 1e-4),
                            rtols=(1e-6, 1e-8) if quick else (1e-4, 1e-6, 1e-8))
    emit("label agreement with the reference over the map:")
    for (m, s), frac in agree.items():
        emit(f"  {m:<7}{s:>8.0e}  {100 * frac:6.1f} %")
    coarse_dt = max((s for (m, s), f in agree.items() if m == "rk4" and f == 1.0), default=None)
    loose_tol = max((s for (m, s), f in agree.items() if m == "dopri5" and f == 1.0), default=None)
    emit(f"coarsest rk4 dt with every label agreeing: {coarse_dt}; "
         f"loosest dopri5 rtol: {loose_tol}")
    qc = quadrature_check(n=20 if quick else 60)
    emit(f"quadrature (no time stepping) vs integration on {qc['launches']} random launches, "
         "largest disagreement:")
    for k in ("full", "period"):
        w = qc[k]
        emit(f"  {k:<7} theta period {w['period_rel']:.1e} (relative), turn per cycle "
             f"{w['turn_deg']:.1e} deg, theta_max {w['theta_max_deg']:.1e} deg")
    nv = near_vertical_check(n=20 if quick else 40)
    emit(f"near the vertical (theta0 80-89.9 deg), quadrature vs the map's settings on "
         f"{nv['launches']} launches ({nv['fixed_frame']} in the fixed frame), largest error:")
    for k in NEAR_VERTICAL_RUNS:
        emit(f"  {k:<17} turn per cycle {nv[k]['turn_deg']:.1e} deg, n_sides "
             f"{nv[k]['n_sides']:.1e}; round(n) as the quadrature's on {nv[k]['same_n']} of "
             f"{nv['launches']}; label as full rk4's on {nv[k]['same_label']} of {nv['n']}")

    keys = ["pos_err_m", "theta_err_rad", "energy_drift", "jellett_drift", "routh_drift", "wall_s"]
    ds = xr.Dataset(
        {k: ("run", np.array([r[k] for r in rows]), {"units": u, "long_name": k.replace("_", " ")})
         for k, u in zip(keys, ["m", "rad", "1", "kg m3 s-1", "kg m2 s-1", "s"])},
        coords={"case": ("run", [r["case"] for r in rows]),
                "method": ("run", [r["method"] for r in rows]),
                "setting": ("run", [r["setting"] for r in rows],
                            {"long_name": "dt (s) for rk4, rtol for dopri5"}),
                "label": ("run", [r["label"] for r in rows])},
        attrs={"Conventions": "CF-1.10", "title": "ballsurvey work-precision report",
               "coarsest_rk4_dt_all_labels_agree": coarse_dt or -1.0,
               "loosest_dopri5_rtol_all_labels_agree": loose_tol or -1.0},
    )
    ds.to_netcdf(out / "accuracy.nc")
    ncol = 3
    nrow = math.ceil(len(cs) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.4 * nrow), squeeze=False,
                             constrained_layout=True)
    for ax, c in zip(axes.flat, cs):
        for m, style in (("rk4", "o-"), ("dopri5", "s-")):
            rr = [r for r in rows if r["case"] == c.name and r["method"] == m]
            e = np.array([max(r["pos_err_m"], 1e-16) for r in rr])
            ax.loglog([r["wall_s"] for r in rr], e, style, label=m)
        ax.axhline(max(gaps[c.name], 1e-16), color="grey", ls=":", lw=1, label="ref vs fixed frame")
        ax.set_title(f"{c.name} (T = {c.T:g} s)", fontsize=10)
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel("final position error (m)")
        ax.legend(fontsize=7)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    for ax in list(axes.flat)[len(cs):]:
        ax.set_visible(False)
    fig.savefig(out / f"accuracy.{fig_format}", dpi=100)
    plt.close(fig)
    emit(f"wrote {out / 'accuracy.nc'} and {out / f'accuracy.{fig_format}'}")
    return {"rows": rows, "ensemble": ens, "agreement": agree, "coarsest_dt": coarse_dt,
            "loosest_rtol": loose_tol}
