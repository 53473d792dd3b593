"""``friction-sim reduction`` (issue 22, item 4): the paper's friction-reduction claim in one command."""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import pytest

from friction_sim.core.meanspeed.urelation import u_map

BIN = Path(sys.executable).parent


def test_the_curves_under_lomakin_s_conditions(tmp_path: Path) -> None:
    png = tmp_path / "reduction.png"
    done = subprocess.run([str(BIN / "friction-sim"), "reduction", "--png", str(png), "--points", "11"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert png.stat().st_size > 10_000 and "mu = 0.156" in done.stdout and "f = 100 Hz" in done.stdout
    rows = list(csv.DictReader((tmp_path / "reduction.csv").open()))
    assert {r["view"] for r in rows} == {"speed", "amplitude"} and len(rows) == 4 * 11 + 3 * 11
    for row in rows:
        if not row["apparent_friction_ratio"]:
            continue  # beyond the fastest stick-slip at that ratio
        phi, ratio, speed = float(row["apparent_friction_ratio"]), float(row["amplitude_ratio"]), float(
            row["mean_speed"])
        assert float(row["apparent_friction"]) == pytest.approx(0.156 * phi, rel=1e-15)
        if ratio > 0.0:  # the forward relation gives back the speed (U = V f/(g mu))
            assert u_map(phi, ratio) * 10.0 * 0.156 / 100.0 == pytest.approx(speed, rel=1e-11, abs=1e-18)
    for ratio in (0.2, 0.4, 0.6, 0.8):  # every curve keeps its exact end point: U = a/(2 pi), phi = 1
        last = [r for r in rows if r["view"] == "speed" and float(r["amplitude_ratio"]) == ratio][-1]
        assert last["apparent_friction_ratio"] == "1.0"
        assert float(last["mean_speed"]) == pytest.approx(ratio * 10.0 * 0.156 / (2 * math.pi * 100.0), rel=1e-15)
    first = next(r for r in rows if r["view"] == "speed" and float(r["amplitude_ratio"]) == 0.4)
    assert float(first["mean_speed"]) == 0.0 and float(first["apparent_friction_ratio"]) == pytest.approx(0.6)
    assert math.isclose(float(first["apparent_friction"]), 0.156 * 0.6, rel_tol=1e-15)


def test_a_bad_list_is_refused_in_one_line(tmp_path: Path) -> None:
    done = subprocess.run([str(BIN / "friction-sim"), "reduction", "--png", str(tmp_path / "x.png"), "--speeds",
                           "0.001,fast"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "speeds" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "x.png").exists()
