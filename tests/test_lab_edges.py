"""The lab bench commands' edges, found by an adversarial pass: each input error is one line with
exit status 2 before any work, and an output that cannot be written is named."""
from __future__ import annotations

import os

import numpy as np
import pandas as pd
import pytest

import ballsurvey
from ballsurvey.cli import main

SQUARE = ["--theta0-deg", "-5", "--chidot0", "4.05", "--phidot0", "-3"]


def _one_line(capsys):
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def test_fit_refuses_a_probe_length_for_a_centre_track(tmp_path, capsys):
    # a KeyError traceback before: --probe-m on a track of x, y
    ds = ballsurvey.simulate(-5.0, 0.0, 4.05, -3.0, T=1.0, n_out=301)
    track = tmp_path / "t.csv"
    pd.DataFrame({"t": ds.time.values, "x": ds.x.values, "y": ds.y.values}).to_csv(track,
                                                                                  index=False)
    assert main(["fit", str(track), "--probe-m", "0.03"]) == 2
    assert "--probe-m" in _one_line(capsys)


def test_a_launch_is_checked_against_the_ball_given(tmp_path, capsys):
    # -40 deg rests the paper's ball on its flat face (below -31.8 deg) but not a ball with a
    # 1 mm cap cut off (its flat face touches below -73.9 deg): it was refused for the paper's
    launch = ["--theta0-deg", "-40", "--chidot0", "4.05", "--phidot0", "-3", "--T", "0.5"]
    assert main(["path", *launch, "--cut-height", "0.001", "-o", str(tmp_path / "a.png")]) == 0
    assert main(["path", *launch, "-o", str(tmp_path / "b.png")]) == 2
    assert "flat face" in _one_line(capsys)
    assert not (tmp_path / "b.png").exists()


def test_path_refuses_a_forces_file_it_cannot_write_before_any_work(tmp_path, capsys):
    (tmp_path / "q-forces.png").mkdir()
    out = tmp_path / "q.png"
    assert main(["path", *SQUARE, "--T", "0.5", "--forces", "-o", str(out)]) == 2
    assert "q-forces.png" in _one_line(capsys)
    assert not out.exists()  # refused before the path figure was written


def test_animate_refuses_an_output_under_a_file_before_integrating(tmp_path, capsys):
    (tmp_path / "good.csv").write_text("t,x,y\n")
    assert main(["animate", *SQUARE, "--T", "0.5", "-o",
                 str(tmp_path / "good.csv" / "x.gif")]) == 2
    assert "not a folder" in _one_line(capsys)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full here")
def test_a_full_disk_names_the_file(tmp_path, capsys):
    (tmp_path / "full.png").symlink_to("/dev/full")
    assert main(["path", *SQUARE, "--T", "0.5", "-o", str(tmp_path / "full.png")]) == 1
    err = _one_line(capsys)
    assert "full.png" in err and "No space left" in err


def test_an_interrupted_animation_leaves_no_file(tmp_path, monkeypatch):
    from ballsurvey import animate

    ds = ballsurvey.simulate(-5.0, 0.0, 4.05, -3.0, T=0.3, n_out=61)
    drawn = animate.frames

    def interrupted(*a, **kw):  # Ctrl-C once some frames are drawn and the file begun
        pictures = drawn(*a, **kw)
        yield next(pictures)
        open(tmp_path / ".cc.partial.gif", "wb").write(b"GIF89a")
        raise KeyboardInterrupt
    monkeypatch.setattr(animate, "frames", interrupted)
    with pytest.raises(KeyboardInterrupt):
        animate.write_animation(ds, tmp_path / "cc.gif")
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    assert np.isfinite(ds.x.values).all()


def test_fit_refuses_a_gap_and_a_huge_track_in_one_line(tmp_path, capsys):
    # the median spacing alone was checked: a last sample moved to t = 5 s was fitted (slowly),
    # and a 1e6-row track took minutes and 1.7 GB
    ds = ballsurvey.simulate(-5.0, 0.0, 4.05, -3.0, T=1.0, n_out=301)
    t = ds.time.values.copy()
    t[-1] = 5.0
    gap = tmp_path / "gap.csv"
    pd.DataFrame({"t": t, "x": ds.x.values, "y": ds.y.values}).to_csv(gap, index=False)
    assert main(["fit", str(gap)]) == 2
    assert "sample 301 (t = 5 s)" in _one_line(capsys)
    n = 200_001
    huge = tmp_path / "huge.csv"
    tt = np.arange(n) / 1000.0
    pd.DataFrame({"t": tt, "x": 0.01 * np.sin(tt), "y": 0.01 * np.cos(tt)}).to_csv(huge,
                                                                               index=False)
    assert main(["fit", str(huge)]) == 2
    assert "200001 samples" in _one_line(capsys)
