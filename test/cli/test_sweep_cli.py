"""``friction-sim sweep`` and ``sweep-report`` from the command line: a sweep
runs, resumes and reports; every bad input is one line and exit code 2."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from friction_sim.cli.main import main
from friction_sim.io.parquet import read_table, write_table

SWEEP = """\
name: tiny
settle_periods: 4
periods: 6
chunk_size: 8
seed: 2
fixed: {drive_force: 0.0, mu: 0.3}
grid:
  track_inclination: [0, 5]
  throw_number: [0.5, 1.5, 2.5]
  excitation_angle: [30, 60, 90]
samples: 2
random:
  mass: {distribution: lognormal, median: 0.01, sigma: 0.2}
"""


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_a_sweep_runs_resumes_and_reports(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "tiny.yaml"
    path.write_text(SWEEP)
    output = tmp_path / "tiny.parquet"
    code, out, err = cli(capsys, "sweep", str(path), "--output", str(output), "--workers", "0", "--engine", "scalar")
    assert code == 0, err
    assert "36 points x 10 periods in 5 chunk(s) of 8 (in this process)" in err and "5/5 chunks  36/36 points" in err
    assert re.search(r"wrote .*tiny.parquet: 36 points, 5 chunk\(s\) computed, 0 reused", out)
    code, out, _ = cli(capsys, "sweep", str(path), "--output", str(output), "--workers", "0")
    assert code == 0 and "0 chunk(s) computed, 5 reused" in out and "already complete" in out

    code, out, err = cli(capsys, "sweep-report", str(output), "--x", "throw_number", "--y", "excitation_angle",
                         "--output", str(tmp_path / "report"))
    assert code == 0, err
    stem = tmp_path / "report" / "tiny_mean_velocity_throw_number_excitation_angle"
    assert stem.with_suffix(".png").stat().st_size > 10_000 and stem.with_suffix(".md").is_file()
    from PIL import Image

    with Image.open(stem.with_suffix(".png")) as image:
        assert round(image.info["dpi"][0]) == 150
    # the optimum per slice: the best cell of each inclination, its mean over the 2 parts and their spread
    columns = read_table(output)[0]
    rows = [line for line in out.splitlines() if line.startswith("| ") and line[2].isdigit()]
    assert len(rows) == 2
    for row, inclination in zip(rows, (0.0, 5.0)):
        cells = [cell.strip() for cell in row.strip("|").split("|")]
        here = columns["track_inclination"] == inclination
        means = {(g, b): columns["mean_velocity"][here & (columns["throw_number"] == g)
                                                  & (columns["excitation_angle"] == b)]
                 for g in (0.5, 1.5, 2.5) for b in (30.0, 60.0, 90.0)}
        best = max(means, key=lambda key: float(np.mean(means[key])))
        assert cells[0] == f"{inclination:g}" and (float(cells[1]), float(cells[2])) == best
        assert float(cells[3]) == pytest.approx(np.mean(means[best]), rel=1e-5)
        assert float(cells[4]) == pytest.approx(np.std(means[best]), rel=1e-2)
        assert cells[5] == "2"
    report = stem.with_suffix(".md").read_text()
    assert "## Optimum per slice" in report and "tiny.yaml" in report


@pytest.mark.parametrize(("args", "message"), [
    (["sweep", "{bad}"], r"\{bad\}: line 3: mu = -1.0 rejected: must be in \[1e-06, 10\]$"),
    (["sweep", "{good}", "--workers", "-1"], r"argument --workers: '-1' rejected|-1 rejected: must be an integer"),
    (["sweep", "{good}", "--chunk-size", "0"],
     r"--chunk-size: chunk_size = 0 rejected: must be an integer in \[1, 10000000\] points"),
    (["sweep", "{good}", "--output", "{tmp}/r.csv"], r"--output = '.*r.csv' rejected: must end in .parquet$"),
    (["sweep", "{tmp}/missing.yaml"], r"missing.yaml: cannot read: No such file or directory$"),
    (["sweep", "{good}", "--scheduler", "tcp://127.0.0.1:{port}", "--connect-timeout", "1"],
     r"--scheduler tcp://127.0.0.1:\d+: no Dask scheduler answered"),
    (["sweep-report", "{tmp}/none.parquet", "--x", "mu", "--y", "mass"], r"results = '.*none.parquet' rejected"),
    (["sweep-report", "{foreign}", "--x", "mu", "--y", "mass"], r"not the results of friction-sim sweep"),
    (["sweep-report", "{good}", "--x", "mu", "--y", "mass"], r"not a readable Parquet file"),
    (["sweep-report", "{results}", "--x", "mu", "--y", "mu"], r"--x and --y are both 'mu'"),
    (["sweep-report", "{results}", "--x", "speed", "--y", "mu"], r"no column 'speed'; inputs and outputs: "),
    (["sweep-report", "{results}", "--x", "mu", "--y", "mass", "--slice", "mass"],
     r"--slice mass: it is already the y axis$"),
])
def test_bad_input_is_one_line_and_exit_code_2(tmp_path: Path, args: list[str], message: str) -> None:
    good = tmp_path / "good.yaml"
    good.write_text("periods: 2\ngrid:\n  mu: [0.1, 0.2]\n  mass: [1, 2]\n")
    (tmp_path / "bad.yaml").write_text("periods: 2\nfixed:\n  mu: -1\n")
    write_table(tmp_path / "foreign.parquet", {"a": np.arange(3)}, {})
    results = tmp_path / "results.parquet"
    if "{results}" in args:
        assert main(["sweep", str(good), "--workers", "0", "--output", str(results), "--quiet"]) == 0
    # A port where no scheduler is: bound here for the whole test and never listening, so a
    # connection to it is refused, and no other process can start listening there meanwhile.
    with socket.socket() as unheard:
        unheard.bind(("127.0.0.1", 0))
        filled = [a.format(bad=tmp_path / "bad.yaml", good=good, tmp=tmp_path, port=unheard.getsockname()[1],
                           foreign=tmp_path / "foreign.parquet", results=results) for a in args]
        done = subprocess.run([sys.executable, "-m", "friction_sim", *filled], capture_output=True, text=True,
                              timeout=60, check=False)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2, done.stderr
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert re.search(message, lines[0].replace(str(tmp_path / "bad.yaml"), "{bad}")), lines[0]


def test_the_sweeps_tutorial_shows_the_example_sweep_as_shipped() -> None:
    root = Path(__file__).resolve().parents[2]
    section = (root / "doc" / "tutorials" / "sweeps.md").read_text()
    block = re.search(r"```yaml\n(.*?)```", section, re.S)
    assert block is not None
    shipped = (root / "config" / "sweep_example.yaml").read_text()
    assert shipped.split("\n", 1)[1] == block.group(1)
