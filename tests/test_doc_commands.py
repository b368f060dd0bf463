"""Every `ballsurvey` command printed in README.md and docs/*.md runs as printed: the cheap ones
are run here, in order, in a folder laid out like a fresh clone (`sweeps/`, `examples/`, an empty
`results/`), and write nowhere but under `results/`. The expensive ones are listed below, each
with the reason it is not run; a new command in the docs must be run or listed, or this fails.

A command is a line of a code block (fenced or indented) or an inline code span that starts with
`ballsurvey`, `.venv/bin/ballsurvey` or `$ ballsurvey`. A form with placeholders (`SPEC.toml`,
`N`, `...`, `[--threads N]`) is not a command, nor is an inline mention that the command line
refuses for want of its arguments (`ballsurvey sweep -v`, `ballsurvey fit --format json`): prose
naming a command or an option. A code block's command must parse."""
import contextlib
import io
import re
import shlex
import shutil
from pathlib import Path

import pytest

from ballsurvey.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]

# not run: command -> why
SKIP = {
    "ballsurvey explore results/quick.nc": "serves the app until stopped (tests/test_explore.py "
                                           "drives the app in Chromium)",
    "ballsurvey explore results/quick.nc --html results/quick.html":
        "integrates all 108 paths of the map, ~10 s (tests/test_explore.py writes and opens a "
        "page)",
    "ballsurvey sweep sweeps/square-map.toml": "1845 launches, ~17 s",
    "ballsurvey plot results/square-map.nc": "needs the square map, not made here",
    "ballsurvey fit examples/track-square.csv -o results/fit.png":
        "a fit, ~10 s (tests/test_fit.py fits a track made like the shipped one)",
    "ballsurvey fit examples/track-square.csv": "a fit, ~10 s (as above)",
    "ballsurvey fit examples/track-tracker.txt --units cm -o results/fit-tracker.png":
        "a fit, ~10 s (tests/test_fit_lab.py fits the shipped Tracker file by the command line)",
    "ballsurvey bench --backend cuda": "needs a CUDA GPU",
    "ballsurvey animate --theta0-deg -5 --chidot0 4.05 --phidot0 -3 --T 3 -o results/square.gif":
        "the README's animate command with its default --T 3 written out (run above)",
    "ballsurvey animate --theta0-deg -10 --chidot0 2.3 --phidot0 -2.5 --T 3 -o "
    "results/triangle.mp4": "MP4 needs ffmpeg (tests/test_lab_edges.py checks the one-line "
                            "refusal without it)",
    "ballsurvey paper": "integrates and draws the paper's six cases, ~1 min",
    "ballsurvey accuracy": "a work-precision report, minutes",
    "ballsurvey accuracy --ensemble": "a work-precision report, minutes",
    "ballsurvey bench": "a benchmark",
    "ballsurvey bench --headline": "a benchmark: a million launches",
    "ballsurvey bench --headline 100": "a benchmark: a million launches",
    "ballsurvey bench --period 40": "a benchmark",
    "ballsurvey bench --map 64": "a benchmark",
    "ballsurvey bench --spec sweeps/square-map.toml": "a benchmark",
    "ballsurvey bench --scaling --headline 100 --threads 2 --workers 2": "a benchmark",
    "ballsurvey bench --headline --backend cuda": "needs a CUDA GPU",
    "ballsurvey bench --backend cuda --launches 4194304": "needs a CUDA GPU",
    "ballsurvey sweep sweeps/gpu-1e8.toml": "1e8 launches on a GPU",
    "ballsurvey plot results/quadrature-1e8.nc --at phidot0=-3":
        "needs the 1e8-launch map (sweeps/quadrature-1e8.toml, ~10 min), not made here",
    "ballsurvey query results/quadrature-1e8.nc --shape square --limit 5":
        "needs the 1e8-launch map, not made here (tests/test_plot_query.py queries by slabs)",
    "ballsurvey explore results/quadrature-1e8.nc --at phidot0=-3 --html results/q1e8.html":
        "needs the 1e8-launch map, not made here",
    "ballsurvey sweep h.toml -v": "h.toml is the headline spec the page writes first (a million "
                                  "launches)",
}
# run with these arguments appended (argparse keeps the last of an option), to stay cheap
TINY = {
    "ballsurvey refine --theta0 -10 30 --chidot0 1 12 --phidot0 -3 --coarse 9 --levels 4":
        ["--coarse", "3", "--levels", "1", "--T", "2"],
}
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _code_lines(text):
    """The lines of the code blocks of Markdown `text`: fenced, or indented by 4 spaces after a
    blank line."""
    out, fence, prev_blank, indented = [], None, True, False
    for line in text.splitlines():
        s = line.strip()
        if fence:
            if s.startswith(fence):
                fence = None
            else:
                out.append(s)
        elif s.startswith(("```", "~~~")):
            fence = s[:3]
        elif line.startswith("    ") and (prev_blank or indented):
            indented = True
            out.append(s)
        elif s:
            indented = False
        prev_blank = not s
    return out


def _normal(cmd):
    """`cmd` without a prompt, a venv prefix or a trailing comment, its spaces single."""
    cmd = re.sub(r"^\$ ", "", cmd.strip())
    cmd = re.sub(r"^\.venv/bin/", "", cmd)
    cmd = re.sub(r"\s+#.*$", "", cmd)
    return " ".join(cmd.split())


def _is_form(cmd):
    return any(t == "..." or t.startswith("[") or "NAME" in t
               or re.fullmatch(r"[A-Z][A-Z0-9_]*(\.[a-z]+)?", t) for t in shlex.split(cmd))


def documented_commands():
    """{command: page} in the order the pages print them, first occurrence of each; an inline
    mention the command line refuses is left out."""
    commands = set(build_parser().commands)
    seen = {}
    for page in PAGES:
        text = page.read_text()
        found = [(_normal(s), True) for s in _code_lines(text)
                 if re.match(r"(\$ )?(\.venv/bin/)?ballsurvey( |$)", s)]
        found += [(_normal(s), False)
                  for s in re.findall(r"`((?:\.venv/bin/)?ballsurvey [^`]+)`", text)]
        for cmd, in_block in found:
            words = cmd.split()
            if len(words) < 2 or not (words[1] in commands or words[1].startswith("-")):
                continue  # a message quoted in prose ("ballsurvey find: no solution ...")
            if _is_form(cmd) or (not in_block and _refused(cmd)):
                continue
            seen.setdefault(cmd, page.name)
    return seen


def _refused(cmd):
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            build_parser().parse_args(shlex.split(cmd)[1:])
    except SystemExit as exc:
        return exc.code != 0
    return False


def test_the_pages_print_commands_and_this_file_knows_them():
    found = documented_commands()
    # the README's five minutes and lab bench are among them
    for cmd in ("ballsurvey sweep sweeps/quick.toml", "ballsurvey plot results/quick.nc",
                "ballsurvey find --shape square --theta0-deg -5 --phidot0 -3"):
        assert cmd in found, cmd
    stale = [c for c in list(SKIP) + list(TINY) if c not in found]
    assert not stale, f"listed here but printed nowhere: {stale}"


def test_every_output_a_command_names_is_under_results():
    for cmd, page in documented_commands().items():
        words = cmd.split()
        for opt, value in zip(words, words[1:]):
            if opt in ("-o", "--output", "--html"):
                assert value.startswith("results/"), f"{page}: {cmd}"


def test_the_cheap_commands_run_as_printed_and_write_only_under_results(tmp_path, monkeypatch,
                                                                          capsys):
    for name in ("sweeps", "examples"):
        shutil.copytree(ROOT / name, tmp_path / name)
    (tmp_path / "results").mkdir()
    before = set(tmp_path.rglob("*"))
    monkeypatch.chdir(tmp_path)
    ran = []
    for cmd, page in documented_commands().items():
        if cmd in SKIP:
            continue
        code = main(shlex.split(cmd)[1:] + TINY.get(cmd, []))
        out = capsys.readouterr()
        assert code == 0, f"{page}: `{cmd}` exited {code}: {out.err[-800:]}"
        ran.append(cmd)
    assert len(ran) >= 15, ran
    new = sorted(str(p.relative_to(tmp_path)) for p in set(tmp_path.rglob("*")) - before
                 if p.is_file())
    assert new, "the commands wrote nothing"
    outside = [p for p in new if not p.startswith("results/")]
    assert not outside, f"written outside results/: {outside}"


@pytest.mark.parametrize("page", ["README.md", "docs/index.md", "docs/lab.md"])
def test_pictures_the_pages_show_come_from_results(page):
    """The commands a page prints for its pictures write under results/ (a fresh clone that
    follows the page gets no untracked file: .gitignore keeps results/ out)."""
    ignore = (ROOT / ".gitignore").read_text().split()
    assert "results/*" in ignore
    text = (ROOT / page).read_text()
    assert not re.search(r" -o (?!results/)\S+\.(png|gif|mp4|pdf|svg)\b", text), page
