"""Too few observer samples per theta cycle give no shape: `unresolved`, with the reason in the
sweep's summary. The paper's six launches carry the paper's own words (its Figs. 4, 7, 9a, 9c,
12a, 12b), so a label is judged against the paper, not against this code."""
from __future__ import annotations

import numpy as np
import pytest

from ballsurvey.ball import Ball
from ballsurvey.classify.labels import LABELS
from ballsurvey.classify.observer import N_OBS
from ballsurvey.cli import main
from ballsurvey.compose import OBSERVER, classify, near_vertical_fallback, run_launches
from ballsurvey.integrate import ensemble
from ballsurvey.paper import FIGURES, fig4_launch
from ballsurvey.units import StepPlan, fields_to_si, launch_state

BALL = Ball.paper()
TU = BALL.time_unit
#: the path each of the paper's launches traces, in the paper's words
PAPER = {"fig4": "circle", "fig7": "near_straight", "fig9a": "circle", "fig9c": "circle",
         "fig12a": "square", "fig12b": "triangle"}


def _paper_map(method, dt, observe_every, sampling=False):
    """The paper's six launches for 6 s: labels and samples per cycle. sampling: RK4 with the
    sampling observer (the CUDA backend's), every observe_every steps, instead of the map's."""
    f = [dict(FIGURES[k]) for k in PAPER]
    f[0].update(fig4_launch(BALL)[0])  # the steady circle's spin, from the paper's Eq. (28)
    y0 = launch_state(np.array([x["theta0_deg"] for x in f]), 0.0,
                      np.array([x["chidot0"] for x in f]), np.array([x["phidot0"] for x in f]),
                      TU, chi0_deg=np.array([x.get("chi0_deg", 0.0) for x in f]))
    p = np.repeat(BALL.nondim_params()[:, None], len(f), 1)
    plan = StepPlan(6.0, dt, TU)
    if sampling:
        res = ensemble.integrate(y0, p, plan.dt_nd, plan.n_steps, method, observer=OBSERVER,
                                 n_slots=N_OBS, observe_every=observe_every, parallel=False)
        near_vertical_fallback(y0, p, plan.T_nd, res, parallel=False)
    else:
        res = run_launches(y0, p, plan, method, observe_every=observe_every)
    out = fields_to_si(classify(res, BALL.flat_face_theta_rad), BALL.a, TU, BALL.M)
    return [LABELS[k] for k in out["label"]], out["samples_per_cycle"]


@pytest.mark.parametrize("dt,every", [(1e-4, 5000), (1e-3, 400), (1e-3, 100)])
def test_sparse_samples_give_no_wrong_shape(dt, every):
    # samples every 0.1-0.5 s against theta periods of 0.3-0.6 s: sampled so, the square was
    # called a rosette, the triangle a star
    labels, samples = _paper_map("rk4", dt, every, sampling=True)
    for (name, want), got in zip(PAPER.items(), labels):
        assert got in (want, "unresolved"), (name, got)
    assert labels.count("unresolved") >= 4, labels


@pytest.mark.parametrize("dt,every", [(1e-4, 5000), (1e-3, 400), (1e-3, 100)])
def test_a_fixed_step_map_is_observed_as_its_interpolants_need(dt, every):
    # the map's RK4 feeds the step observer at each launch's own cadence, whatever
    # observe_every (there only the validity checks' cadence): the paper's words at any
    labels, samples = _paper_map("rk4", dt, every)
    assert labels == list(PAPER.values())
    assert (samples[1:] >= 40).all(), samples


@pytest.mark.parametrize("dt", [0.1, 0.02, 1e-3])
def test_the_step_observer_needs_no_sampling(dt):
    # dop853's observer reads each step's interpolant (three points a step, extrema located):
    # [run] dt is only its first trial step, and the paper's six get the paper's words at any
    labels, samples = _paper_map("dop853", dt, 4)
    assert labels == list(PAPER.values())
    assert (samples[1:] >= 20).all(), samples


def test_the_map_settings_resolve_the_papers_launches():
    labels, samples = _paper_map("dop853", 1e-3, 4)  # the big map's settings: 4 ms samples
    assert labels == list(PAPER.values())
    assert (samples[1:] > 40).all(), samples  # fig4 is steady: one cycle never completes


@pytest.mark.parametrize("run, reason, not_said", [
    # dop853 this loose sees too few points a cycle: a smaller rtol mends it
    ('T = 4.0\nmethod = "dop853"\nrtol = 1e-2\natol = 1e-3\n',
     "too few observer samples per theta cycle (under 20): 1", "complete theta cycles"),
    # fig12a's theta cycle is 0.57 s: 0.4 s holds none of the two complete cycles the labels
    # need, which a smaller dt does not mend
    ("T = 0.4\n", "fewer than 2 complete theta cycles in T: 1; raise [run] T",
     "too few observer samples"),
])
def test_sweep_summary_names_the_reason(tmp_path, capsys, run, reason, not_said):
    spec = tmp_path / "s.toml"
    spec.write_text('[[points]]\nname = "fig12a"\ntheta0_deg = -5.0\nthetadot0 = 0.0\n'
                    f'chidot0 = 4.05\nphidot0 = -3.0\n[run]\n{run}'
                    f'[output]\nfile = "{tmp_path / "m.nc"}"\n')
    assert main(["sweep", str(spec)]) == 0
    out = capsys.readouterr().out
    assert reason in out and not_said not in out, out
