"""Shared fixtures. The paper's launches come from `ballsurvey.paper.FIGURES`, the one table."""
import numpy as np
import pytest

from ballsurvey.ball import Ball
from ballsurvey.paper import FIGURES
from ballsurvey.paper import fig4_launch as paper_fig4_launch


@pytest.fixture(scope="session")
def ball():
    return Ball.paper()


@pytest.fixture(scope="session")
def p(ball):
    return ball.nondim_params()


@pytest.fixture(scope="session")
def paper_launches():
    """The paper's numerical launches but Fig. 4 (as its text gives them; docs/physics.md), as
    `simulate` keywords: theta0_deg, thetadot0, chidot0, phidot0 (rad/s), chi0_deg."""
    return {k: {n: v for n, v in d.items() if n != "T_fig"}
            for k, d in FIGURES.items() if k != "fig4"}


@pytest.fixture(scope="session")
def fig4(ball):
    """Fig. 4: theta0 = 24 deg, chidot0 = -3.23 rad/s, phidot0 from Eq. (28), start at y = -R.
    (simulate keywords, R in m)."""
    extra, R = paper_fig4_launch(ball)
    return dict(theta0_deg=24.0, thetadot0=0.0, chidot0=-3.23, **extra), R


@pytest.fixture(scope="session")
def random_euler_states():
    """random_euler_states(n, seed): n random Euler states (n, 8), tilts within +-80 deg."""
    def make(n, seed=0):
        rng = np.random.default_rng(seed)
        u = np.empty((n, 8))
        u[:, 0:2] = rng.normal(0, 1, (n, 2))
        u[:, 2] = rng.uniform(-1.4, 1.4, n)
        u[:, 3:5] = rng.uniform(-4, 4, (n, 2))
        u[:, 5:8] = rng.normal(0, 2, (n, 3))
        return u
    return make


@pytest.fixture(scope="session")
def big_spec_text():
    """A one-chunk map of 2000 launches that runs for some seconds: one to interrupt."""
    return """
title = "interrupt me"
[launch]
theta0_deg = {start = -10.0, stop = 30.0, num = 40}
thetadot0 = 0.0
chidot0 = {start = 1.0, stop = 12.0, num = 50}
phidot0 = -3.0
[run]
T = 10.0
dt = 2e-4
[output]
file = "big.nc"
"""


def headless_chromium(window: str = "1250,1000"):
    """A headless Chromium driven by selenium (Debian's chromium and chromedriver), at `window`
    pixels ("width,height"); skips the test, saying why, where there is none."""
    import os
    import shutil

    chrome = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")
                   if shutil.which(n)), None)
    driver = shutil.which("chromedriver") or next(
        (p for p in ("/usr/lib/chromium/chromedriver", "/usr/bin/chromedriver")
         if os.path.exists(p)), None)
    if not (chrome and driver):
        pytest.skip("no headless browser: chromium and chromedriver not found (Debian: apt-get "
                    "install chromium chromium-driver)")
    webdriver = pytest.importorskip("selenium.webdriver")
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              f"--window-size={window}"):
        opts.add_argument(a)
    opts.binary_location = chrome
    return webdriver.Chrome(options=opts, service=Service(driver))
