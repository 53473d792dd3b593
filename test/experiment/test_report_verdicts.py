"""The report tells the verdict: each ``expect`` entry judged in the band it
states, printed with PASS or FAIL and what was measured, in the Markdown
report too, and exit 1 when one fails (so a scenario stands in CI as a test),
from the live run (``experiment``) and from its recording alone (``report``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from friction_sim.experiment.metrics import settling_periods
from friction_sim.experiment.report import build_report, run_data_from_recording

SCENARIO = """\
name: {name}
duration: 1.2
lockstep: true
plant:
  drive_force: 0.7
  excitation_amplitude: 5.0
controller:
  target_speed: 0.0002
schedule:
  - {{t: 0.4, target_speed: {target}}}
  - {{t: 0.8, target_speed: 0.00015}}
expect:
  - {{t: 0.4, within: {within}, periods: {periods}}}
  - {{t: 0.8, within: 0.02, periods: 5}}
"""
FRICTION_SIM = Path(sys.executable).parent / "friction-sim"


def _run(tmp_path: Path, name: str, within: float, periods: int,
         target: float = 3e-4) -> tuple[subprocess.CompletedProcess[str], Path]:
    scenario = tmp_path / f"{name}.yaml"
    scenario.write_text(SCENARIO.format(name=name, within=within, periods=periods, target=target))
    done = subprocess.run([str(FRICTION_SIM), "experiment", str(scenario), "--output", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    return done, tmp_path / f"{name}.mcap"


def _verdicts(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.lstrip("- ").startswith("expect t = ")]


def test_met_expectations_pass_with_what_was_measured_and_exit_0(tmp_path: Path) -> None:
    done, recording = _run(tmp_path, "met", 0.01, 5)
    assert done.returncode == 0, done.stderr
    lines = _verdicts(done.stdout)
    assert [line.split(":")[0] for line in lines] == ["expect t = 0.4 s", "expect t = 0.8 s"]
    assert all(": PASS (settled in " in line for line in lines), lines
    assert "within 1 % in <= 5 periods" in lines[0] and "within 2 % in <= 5 periods" in lines[1]
    assert _verdicts((tmp_path / "met.md").read_text()) == [f"- {line}" for line in lines]
    again = subprocess.run([str(FRICTION_SIM), "report", str(recording), "--output", str(tmp_path / "again")],
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 0 and _verdicts(again.stdout) == lines, again.stderr


def test_the_table_settles_each_segment_in_the_band_its_expectation_states(tmp_path: Path) -> None:
    done, recording = _run(tmp_path, "bands", 0.05, 5)
    assert done.returncode == 0, done.stderr
    data = run_data_from_recording(recording)
    assert data.bands == {0.4: 0.05, 0.8: 0.02} and data.band(0.0) == data.tolerance
    for row in build_report(data):
        samples = [(t, v) for t, v in data.all_mean_velocity if row.start < t <= row.end + 1e-9]
        assert row.settling_periods == settling_periods(samples, row.start, row.target, 50.0, data.band(row.start))


@pytest.mark.parametrize("command", ["experiment", "report"])
def test_a_failed_expectation_is_named_and_exits_1(tmp_path: Path, command: str) -> None:
    # 10 mm/s: beyond what the actuator reaches (the controller saturates), so the segment never settles
    done, recording = _run(tmp_path, "unmet", 0.02, 5, target=0.01)
    if command == "report":
        done = subprocess.run([str(FRICTION_SIM), "report", str(recording), "--output", str(tmp_path / "r")],
                              capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stdout + done.stderr
    first, second = _verdicts(done.stdout)
    assert ": FAIL (never settled" in first, first
    assert ": PASS" in second and "Traceback" not in done.stderr
