"""The command line on the general model (issue 11): the model flags reach the
plant, simulate reports flights and every event kind, umap leaves the closed
form where it must, and `friction-sim conveyor` writes a CSV whose numbers
back what it prints."""

from __future__ import annotations

import csv
import itertools
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from friction_sim.cli import options as commands
from friction_sim.cli.main import build_parser
from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.conveyor import point
from friction_sim.core.meanspeed.general import mean_speed, u_general
from friction_sim.core.model import spec
from friction_sim.core.model.events import EventKind
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import is_kostek
from friction_sim.io.export import CONVEYOR_COLUMNS as CSV_COLUMNS

SCRIPT = Path(sys.executable).parent / "friction-sim"

#: Every new model flag, a value off its default, and the field it sets.
MODEL_FLAGS = (("--angle", "30", "excitation_angle", 30.0), ("--phase", "-90", "excitation_phase", -90.0),
               ("--inclination", "5", "track_inclination", 5.0), ("--static-ratio", "1.5", "static_ratio", 1.5),
               ("--restitution", "0.3", "restitution", 0.3),
               ("--landing-friction", "none", "landing_friction", "none"))


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    command = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-m", "friction_sim.cli.main"]
    return subprocess.run([*command, *args], capture_output=True, text=True, timeout=300, cwd=cwd)


def model_argv() -> list[str]:
    return [word for flag, value, _, _ in MODEL_FLAGS for word in (flag, value)]


@pytest.mark.parametrize("command", ["simulate", "trace", "umap"])
def test_the_model_flags_reach_the_params(command: str) -> None:
    extra = {"trace": ["--png", "t.png"], "umap": ["--phi", "0", "--ratio", "2"]}.get(command, [])
    args = build_parser().parse_args([command, *extra, *model_argv(), "--mu", "0.4"])
    params = commands.model(args) if command == "umap" else commands.plant(args)[0]
    expected = SliderParams(mu=0.4, **{name: value for _, _, name, value in MODEL_FLAGS})
    assert params == expected
    defaults = build_parser().parse_args([command, *extra])
    default_params = commands.model(defaults) if command == "umap" else commands.plant(defaults)[0]
    assert default_params == SliderParams() and is_kostek(default_params)


def test_every_plant_setting_is_a_flag_of_simulate_and_trace() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")  # noqa: SLF001 - argparse lists no subparsers publicly
    assert isinstance(sub.choices, dict)
    for name in ("simulate", "trace"):
        options = {o for action in sub.choices[name]._actions for o in action.option_strings}  # noqa: SLF001
        assert {setting.option for setting in spec.PLANT.values()} <= options
    umap_options = {o for action in sub.choices["umap"]._actions for o in action.option_strings}  # noqa: SLF001
    assert {setting.option for setting in commands.MODEL_OPTIONS} <= umap_options


def normal_flight_time(gamma: float, gravity: float, frequency: float) -> float:
    """Flight time of a plastic bouncer under a purely normal excitation, from
    its own equations (independent of the core): lift-off at sin(theta0) = 1/Gamma,
    then z(t) = -g t^2/2 + (A/w) cos(theta0) t - (A/w^2)(sin(theta0 + w t) - sin(theta0)),
    A = Gamma g; the landing is the first positive root."""
    omega = 2.0 * math.pi * frequency
    theta0, amplitude = math.asin(1.0 / gamma), gamma * gravity

    def z(t: float) -> float:
        return (-0.5 * gravity * t * t + amplitude / omega * math.cos(theta0) * t
                - amplitude / omega**2 * (math.sin(theta0 + omega * t) - math.sin(theta0)))

    times = np.linspace(0.01 / frequency, 3.0 / frequency, 30001)  # z > 0 just after, below rounding before
    values = np.array([z(t) for t in times])
    first = int(np.argmax(values < 0.0))
    assert first > 0, "it lands within three periods"
    return float(brentq(z, times[first - 1], times[first], xtol=1e-16, rtol=1e-15))


def test_simulate_json_counts_every_event_kind_and_the_flight_fraction_of_a_hopping_slider() -> None:
    # Gamma = 2 under a purely normal excitation: one hop per period, whatever x does.
    done = run("simulate", "--amplitude", "20", "--drive-force", "0.3", "--duration", "0.5", "--settle", "0.1",
               "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert set(result["events"]) == {kind.value for kind in EventKind}
    slider = Slider(SliderParams(), Inputs(drive_force=0.3, excitation_amplitude=20.0), event_log_size=None)
    slider.advance_to(0.5)
    assert result["events"] == {kind.value: slider.event_counts.get(kind, 0) for kind in EventKind}
    assert result["events"] == {kind.value: sum(e.kind is kind for e in slider.events) for kind in EventKind}
    assert result["events"]["lift_off"] == 25 and result["events"]["landing"] == 25, "one hop per period"
    assert result["throw_number"] == 2.0 and result["U_closed_form"] is False
    flight = normal_flight_time(2.0, 10.0, 50.0)
    theta_land = math.asin(0.5) + 2.0 * math.pi * 50.0 * flight
    assert math.sin(theta_land) < 0.5, "R > 0 at the landing: it stays down until the next lift-off"
    assert result["flight_fraction"] == pytest.approx(flight * 50.0, rel=1e-9)
    assert result["U"] == pytest.approx(result["U_exact"], rel=1e-9) and result["U_periodic"] is True


def test_simulate_text_reports_gamma_and_the_flight_fraction() -> None:
    done = run("simulate", "--angle", "30", "--mu", "0.5", "--amplitude", "20", "--drive-force", "0",
               "--duration", "0.2")
    assert done.returncode == 0, done.stderr
    assert "throw number Gamma = 2, flight fraction" in done.stdout and "lift_off 10, landing 10" in done.stdout


def test_umap_off_the_closed_form_is_the_general_mean_speed() -> None:
    done = run("umap", "--phi", "0", "--ratio", "2", "--angle", "30", "--mu", "0.5", "--json")
    assert done.returncode == 0, done.stderr
    point_ = json.loads(done.stdout)
    params = SliderParams(mu=0.5, excitation_angle=30.0)
    expected = mean_speed(params, Inputs(drive_force=0.0, excitation_amplitude=2.0 * params.weight))
    assert point_["U"] == expected.u and point_["periodic"] == expected.periodic
    assert point_["flight_fraction"] == expected.flight_fraction > 0.0 and point_["throw_number"] == 2.0
    assert "hops" in point_["motion"]
    # Kostek's model above lift-off: no closed form, the general mean speed
    done = run("umap", "--phi", "0.5", "--ratio", "1.5")
    assert done.returncode == 0, done.stderr
    hop = mean_speed(SliderParams(), Inputs(drive_force=0.5 * 0.1 * 10.0, excitation_amplitude=15.0))
    assert done.stdout.splitlines()[0].startswith(f"U(0.5, 1.5) = {hop.u + 0.0!r}")


def test_umap_grid_of_a_general_model_is_u_general(tmp_path: Path) -> None:
    done = run("umap", "--grid", "4", "--angle", "60", "--csv", str(tmp_path / "u.csv"))
    assert done.returncode == 0, done.stderr
    with (tmp_path / "u.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    phi = np.array([float(r["phi"]) for r in rows])
    a = np.array([float(r["amplitude_ratio"]) for r in rows])
    u = np.array([float(r["U"]) for r in rows])
    np.testing.assert_array_equal(u, u_general(phi, a, SliderParams(excitation_angle=60.0)))


def test_trace_draws_a_flight(tmp_path: Path) -> None:
    done = run("trace", "--png", str(tmp_path / "hop.png"), "--angle", "30", "--mu", "0.5", "--amplitude", "20",
               "--drive-force", "0")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "hop.png").stat().st_size > 20_000


@pytest.fixture(scope="module")
def conveyor(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, list[dict[str, str]], Path]:
    folder = tmp_path_factory.mktemp("conveyor")
    done = run("conveyor", "--png", str(folder / "conveyor.png"), "--points", "21", "--slope-points", "11")
    assert done.returncode == 0, done.stderr
    with (folder / "conveyor.csv").open() as stream:  # beside the PNG by default
        reader = csv.DictReader(stream)
        assert tuple(reader.fieldnames or ()) == CSV_COLUMNS
        rows = list(reader)
    return done.stdout, rows, folder


def test_conveyor_writes_both_panels(conveyor: tuple[str, list[dict[str, str]], Path]) -> None:
    _, rows, folder = conveyor
    assert (folder / "conveyor.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    gamma = [r for r in rows if r["panel"] == "gamma"]
    slope = [r for r in rows if r["panel"] == "inclination"]
    assert len(gamma) == 4 * 21 and len(slope) == 11
    assert sorted({float(r["excitation_angle"]) for r in gamma}) == [15.0, 30.0, 45.0, 60.0]
    assert all(float(r["track_inclination"]) == 0.0 for r in gamma)
    for r in gamma:
        g, u, flight = float(r["throw_number"]), float(r["U"]), float(r["flight_fraction"])
        if g == 0.0:
            assert u == 0.0 and r["periodic"] == "1", "no vibration, no drive: it stays put"
        assert (flight == 0.0) if g <= 1.0 else (flight > 0.0), f"lift-off exactly above Gamma = 1 ({r})"
        assert r["periodic"] in ("0", "1") and (int(r["period_multiple"]) > 0) == (r["periodic"] == "1")
    assert [float(r["track_inclination"]) for r in slope] == list(np.linspace(-20.0, 20.0, 11))


def test_conveyor_prints_each_peak_from_its_curve(conveyor: tuple[str, list[dict[str, str]], Path]) -> None:
    printed, rows, _ = conveyor
    peaks = re.findall(r"beta = (\S+) deg: U peaks at Gamma = (\S+) \(U = (\S+)\)", printed)
    assert [float(angle) for angle, _, _ in peaks] == [15.0, 30.0, 45.0, 60.0]
    for angle, gamma, u in peaks:
        curve = [r for r in rows if r["panel"] == "gamma" and float(r["excitation_angle"]) == float(angle)]
        values = np.array([float(r["U"]) for r in curve])
        best = float(curve[int(np.argmax(values))]["throw_number"])
        assert abs(float(gamma) - best) <= 0.25 + 1e-12, "refined within the coarse peak's cells"
        assert float(u) >= values.max() - 1e-6, "the refined peak is no lower than the grid's"
        assert float(u) == pytest.approx(point(float(angle), 0.0, float(gamma), 0.5).u, abs=1e-6)


def test_conveyor_reversal_is_a_sign_change_of_u(conveyor: tuple[str, list[dict[str, str]], Path]) -> None:
    printed, rows, _ = conveyor
    found = re.search(r"Gamma = (\S+), beta = (\S+) deg: conveying reverses at track inclination alpha = (\S+) deg",
                      printed)
    assert found, printed
    gamma, angle, alpha = (float(v) for v in found.groups())
    slope = [(float(r["track_inclination"]), float(r["U"])) for r in rows if r["panel"] == "inclination"]
    assert all(float(r["throw_number"]) == gamma and float(r["excitation_angle"]) == angle
               for r in rows if r["panel"] == "inclination")
    brackets = [(a0, a1) for (a0, u0), (a1, u1) in itertools.pairwise(slope) if u0 > 0.0 > u1]
    assert len(brackets) == 1 and brackets[0][0] < alpha < brackets[0][1]
    # and the mean speed itself changes sign there (each side a fresh exact simulation)
    assert point(angle, alpha - 1e-4, gamma, 0.5).u > 0.0 > point(angle, alpha + 1e-4, gamma, 0.5).u


@pytest.mark.parametrize("angle", [15.0, 30.0, 45.0, 60.0])
def test_the_marked_gamma_3_30_is_the_one_period_flight(angle: float) -> None:
    """At the figure's marked Gamma = 3.30 (just above sqrt(1 + pi^2)) a plastic
    landing is followed at once by the next lift-off, and the slider, stopped by
    the first impulsive landing, gains Pt cos(theta0)/(m omega) a period in the
    mean: U = cot(beta)/(2 mu) (cos(theta0) = pi/Gamma at the one-period flight)."""
    at_mark = point(angle, 0.0, 3.30, 0.5)
    assert at_mark.periodic and at_mark.flight_fraction == pytest.approx(1.0, abs=1e-12)
    assert at_mark.u == pytest.approx(1.0 / math.tan(math.radians(angle)) / (2.0 * 0.5), rel=1e-9)
