"""``friction-sim resonance`` (issue 21, item 4): the tuning curve a technician sweeps."""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import pytest

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams

BIN = Path(sys.executable).parent


def test_the_tuning_curve_is_the_resonance_curve_and_the_exact_speed(tmp_path: Path) -> None:
    png = tmp_path / "tuning.png"
    done = subprocess.run([str(BIN / "friction-sim"), "resonance", "--png", str(png), "--natural-frequency", "52",
                           "--from", "44", "--to", "60", "--points", "17"], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert png.stat().st_size > 10_000 and "fastest conveying" in done.stdout
    rows = list(csv.DictReader((tmp_path / "tuning.csv").open()))
    assert [float(r["drive_frequency"]) for r in rows] == pytest.approx([44.0 + k for k in range(17)], rel=1e-15)
    zeta = 0.02
    for row in rows:
        r = float(row["drive_frequency"]) / 52.0
        # the resonance curve written independently: |2 zeta r^2 / (1 - r^2 + 2i zeta r)|, 10 ulps apart at most
        h = 2 * zeta * r * r / complex(1 - r * r, 2 * zeta * r)
        assert float(row["amplitude"]) == pytest.approx(0.5 * 10.0 * abs(h), rel=1e-13)
        assert float(row["lag_deg"]) == pytest.approx(math.degrees(-math.atan2(h.imag, h.real)), abs=1e-11)
    at_resonance = next(r for r in rows if float(r["drive_frequency"]) == 52.0)
    assert float(at_resonance["lag_deg"]) == 90.0 and float(at_resonance["amplitude"]) == 5.0
    # each speed is the exact steady motion: the single slider over the same window agrees
    slider = Slider(SliderParams(actuator="resonant", natural_frequency=52.0), Inputs(), cycle_log_size=None)
    slider.advance_to(400 / 50.0 + 0.01)  # the default drive frequency, 50 Hz: its row
    marks = slider.cycle_marks  # the window of the curve: periods 200 to 400 (settle 200, then 200)
    speed = (marks[400].x - marks[200].x) / (200 / 50.0)
    fifty = next(r for r in rows if float(r["drive_frequency"]) == 50.0)
    assert float(fifty["mean_velocity"]) == pytest.approx(speed, rel=1e-9)
    fastest = max(rows, key=lambda r: float(r["mean_velocity"]))
    assert float(fastest["drive_frequency"]) == 52.0


def test_a_range_that_is_not_a_range_is_refused_in_one_line(tmp_path: Path) -> None:
    done = subprocess.run([str(BIN / "friction-sim"), "resonance", "--png", str(tmp_path / "x.png"), "--from", "60",
                           "--to", "40"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "60" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "x.png").exists()
