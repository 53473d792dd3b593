"""The `friction-sim` command line as a user runs it: the installed console
script in a subprocess, checked against the library's exact answers."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from friction_sim.cli.main import build_parser, main
from friction_sim.cli.relation import NEVER_MOVES, SLIPS_ALWAYS, STICK_SLIP, motion_regime
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import dimensional_speed
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import simulate

SCRIPT = Path(sys.executable).parent / "friction-sim"
#: Settings whose flags take a word (their choices), not a number.
TEXT_SETTINGS = {name for name, setting in spec.PLANT.items() if setting.kind is str}


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    command = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-m", "friction_sim.cli.main"]
    return subprocess.run([*command, *args], capture_output=True, text=True, timeout=120, cwd=cwd)


def test_console_script_is_installed() -> None:
    assert SCRIPT.exists(), "make's editable install puts friction-sim in the venv"


def test_help_of_the_command_and_of_every_verb_prints_and_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    """The first thing a newcomer types: ``friction-sim --help`` lists every verb with its
    one-line help as written (a literal % included), and each verb's ``--help`` works."""
    from friction_sim.cli.main import verbs

    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    text = capsys.readouterr().out
    assert exit_info.value.code == 0
    flat = " ".join(text.split())
    for verb in verbs():
        assert verb.name in text and " ".join(verb.help.split()[:4]) in flat, verb.name
        with pytest.raises(SystemExit) as exit_info:
            main([verb.name, "--help"])
        assert exit_info.value.code == 0 and f"usage: friction-sim {verb.name}" in capsys.readouterr().out


def test_umap_point_json_matches_the_relation() -> None:
    done = run("umap", "--phi", "0.7", "--ratio", "0.5", "--json")
    assert done.returncode == 0, done.stderr
    point = json.loads(done.stdout)
    assert point["phi"] == 0.7 and point["amplitude_ratio"] == 0.5
    assert point["U"] == u_map(0.7, 0.5)
    assert point["slip_start_phase"] == pytest.approx(math.asin(0.6), rel=1e-15)
    assert point["moves"] is True


def test_umap_grid_writes_csv_and_png(tmp_path: Path) -> None:
    done = run("umap", "--grid", "11", "--csv", str(tmp_path / "u.csv"), "--png", str(tmp_path / "u.png"))
    assert done.returncode == 0, done.stderr
    with (tmp_path / "u.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 121
    phi = np.array([float(r["phi"]) for r in rows])
    a = np.array([float(r["amplitude_ratio"]) for r in rows])
    u = np.array([float(r["U"]) for r in rows])
    assert np.all((phi > 0) & (phi < 1) & (a > 0) & (a < 1))
    np.testing.assert_array_equal(u, u_map(phi, a))
    # On the boundary phi = 1 - a (to rounding) U is 0 or a few ulp of the exact inputs; never negative.
    assert np.all(u[phi < 1 - a - 1e-12] == 0.0) and np.all(u[phi > 1 - a + 1e-12] > 0.0) and np.all(u >= 0.0)
    assert (tmp_path / "u.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_trace_draws_fig2(tmp_path: Path) -> None:
    done = run("trace", "--png", str(tmp_path / "fig2.png"), "--drive-force", "0.8")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "fig2.png").stat().st_size > 20_000


def test_simulate_json_measures_the_mean_speed() -> None:
    done = run("simulate", "--mass", "2", "--mu", "0.2", "--gravity", "9.81", "--frequency", "80",
               "--amplitude", "9", "--drive-force", "3.2", "--duration", "1", "--settle", "0.1", "--json")
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    phi, a = 3.2 / (0.2 * 2 * 9.81), 9 / (2 * 9.81)
    expected = dimensional_speed(u_map(phi, a), 80.0, 9.81, 0.2)
    assert result["mean_velocity"] == pytest.approx(expected, rel=1e-9)
    assert result["U"] == pytest.approx(u_map(phi, a), rel=1e-9)
    assert result["periods"] == 72
    assert result["events"]["slip_start"] == result["events"]["stick"] == 80


def test_simulate_csv_has_uniform_samples_and_events(tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    done = run("simulate", "--duration", "0.1", "--csv", str(out), "--sample-rate", "1000")
    assert done.returncode == 0, done.stderr
    with out.open() as stream:
        rows = list(csv.DictReader(stream))
    samples = [r for r in rows if r["kind"] == "sample"]
    events = [r for r in rows if r["kind"] != "sample"]
    assert len(samples) == 101
    np.testing.assert_allclose(np.diff([float(r["t"]) for r in samples]), 1e-3, rtol=1e-9)
    assert [r["kind"] for r in events[:2]] == ["slip_start", "stick"]
    assert len(events) == 10
    times = [float(r["t"]) for r in rows]
    assert times == sorted(times)


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("simulate", "--landing-friction", "bogus"), ("--landing-friction", "'bogus'", "impulsive, none")),
        (("umap", "--phi", "0", "--ratio", "2", "--landing-friction", "sticky"), ("--landing-friction", "'sticky'")),
        (("simulate", "--angle", "0"), ("--angle", "excitation_angle", "0.0", "[0.1, 90] deg")),
        (("trace", "--png", "f.png", "--inclination", "95"), ("--inclination", "track_inclination", "95.0", "89")),
        (("simulate", "--restitution", "1"), ("--restitution", "restitution", "1.0", "[0, 0.99]")),
        (("umap", "--phi", "0", "--ratio", "2", "--static-ratio", "0.5"), ("--static-ratio", "0.5", "[1, 100]")),
        (("simulate", "--phase", "200"), ("--phase", "excitation_phase", "200.0", "[-180, 180] deg")),
        (("conveyor", "--png", "c.png", "--points", "3"), ("--points", "3", "[11, 2001]")),
        (("conveyor", "--png", "c.png", "--slope-angle", "0"), ("--slope-angle", "0.0", "[0.1, 90]")),
        (("conveyor",), ("--png",)),
        (("simulate", "--mass", "nan"), ("mass", "nan")),
        (("simulate", "--mu", "-1"), ("mu", "-1.0", "[1e-06, 10]")),
        (("simulate", "--frequency", "0"), ("excitation_frequency", "0.0")),
        (("simulate", "--duration", "0.001"), ("duration", "0.001")),
        (("simulate", "--mass", "heavy"), ("--mass", "heavy")),
        (("umap", "--phi", "0.5", "--ratio", "11"), ("--ratio", "amplitude_ratio", "11.0", "[0, 10]")),
        (("umap",), ("--phi", "--grid")),
        (("nosuchcommand",), ("nosuchcommand",)),
        # NaN, inf and absurd values, refused while parsing, flag, value and limit named
        (("umap", "--phi", "nan", "--ratio", "0.5"), ("--phi", "nan", "finite")),
        (("umap", "--phi", "inf", "--ratio", "0.5"), ("--phi", "inf", "finite")),
        (("umap", "--phi", "-inf", "--ratio", "0.5"), ("--phi", "-inf", "finite")),
        (("umap", "--phi", "1e300", "--ratio", "0.5"), ("--phi", "1e+300", "[-1e+06, 1e+06]")),
        (("umap", "--phi", "0.7", "--ratio", "nan"), ("--ratio", "nan", "finite")),
        (("umap", "--grid", "100000", "--png", "u.png"), ("--grid", "100000", "[2, 2001]")),
        (("umap", "--grid", "1e3", "--png", "u.png"), ("--grid", "'1e3'", "integer")),
        (("trace", "--png", "f.png", "--periods", "1e6"), ("--periods", "1000000.0", "[1, 100]")),
        (("trace", "--png", "f.png", "--periods", "nan"), ("--periods", "nan", "finite")),
        (("simulate", "--duration", "1e9"), ("--duration", "1000000000.0", "1e+07 excitation periods")),
        (("simulate", "--duration", "inf"), ("--duration", "inf", "finite")),
        (("simulate", "--settle", "5"), ("--settle", "5.0", "duration")),
        (("simulate", "--frequency", "inf"), ("--frequency", "excitation_frequency", "inf", "20000")),
        (("simulate", "--csv", "x.csv", "--sample-rate", "1e12"), ("--sample-rate", "1000000000000.0", "1e+09")),
        (("replay", "x.mcap", "--delay", "inf"), ("--delay", "inf", "finite")),
        (("replay", "x.mcap", "--rate", "nan"), ("--rate", "nan", "finite")),
        (("replay", "x.mcap", "--publish", "--delay", "1e300"), ("--delay", "1e+300", "3600")),
        (("replay", "x.mcap", "--verify", "--tolerance", "1e300"), ("--tolerance", "1e+300", "0.01")),
        (("replay", "x.mcap", "--publish", "--rate", "1e-300"), ("--rate", "1e-300", "0.001")),
    ],
)
def test_errors_are_one_line_and_exit_2(args: tuple[str, ...], words: tuple[str, ...], tmp_path: Path) -> None:
    done = run(*args, cwd=tmp_path)
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    for word in words:
        assert word in lines[0]


def numeric_flags() -> list[tuple[str, str]]:
    """(subcommand, option) for every option of every subcommand that takes a number."""
    found = []
    parser = build_parser()
    subcommands = next(a for a in parser._actions if a.choices and a.dest == "command")  # noqa: SLF001 - argparse lists no options publicly
    assert isinstance(subcommands.choices, dict)
    for name, sub in subcommands.choices.items():
        for action in sub._actions:  # noqa: SLF001 - as above
            if action.option_strings and action.type is not None and action.type not in (Path, str) \
                    and action.dest not in TEXT_SETTINGS:
                found.append((name, action.option_strings[-1]))
    return found


def test_the_walk_finds_the_numeric_flags() -> None:
    flags = set(numeric_flags())
    assert {("umap", "--phi"), ("umap", "--ratio"), ("umap", "--grid"), ("trace", "--periods"),
            ("trace", "--mass"), ("simulate", "--duration"), ("simulate", "--sample-rate"),
            ("replay", "--delay")} <= flags


@pytest.mark.parametrize(("command", "flag"), numeric_flags())
@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e999"])
def test_every_numeric_flag_refuses_non_finite_values(command: str, flag: str, value: str,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """Refused while parsing, before anything runs: exit 2, one line with flag and value."""
    with pytest.raises(SystemExit) as exit_:
        main([command, flag, value])
    assert exit_.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    line = lines[0]
    assert flag in line and (value in line or (value == "1e999" and "inf" in line)), line
    assert "finite" in line or "integer" in line, line  # the limit: a finite number, or an integer


@pytest.mark.parametrize(
    ("phi", "ratio", "motion"),
    [(0.7, 0.5, STICK_SLIP), (-0.7, 0.5, STICK_SLIP), (0.2, 0.5, NEVER_MOVES), (0.5, 0.5, NEVER_MOVES),
     (0.0, 0.9, NEVER_MOVES), (1.0, 0.5, SLIPS_ALWAYS), (1.2, 0.5, SLIPS_ALWAYS), (1.2, 0.1, SLIPS_ALWAYS),
     (-3.0, 0.5, SLIPS_ALWAYS), (0.99, 0.0, NEVER_MOVES), (1.01, 0.0, SLIPS_ALWAYS)],
)
def test_the_motion_words_are_what_the_exact_simulation_does(phi: float, ratio: float, motion: str) -> None:
    """A slider of m = 1 kg, mu = 0.1, g = 10 m/s^2 at Fd = phi N and Pa = 10 a N, from rest."""
    assert motion_regime(phi, ratio)[0] == motion
    result = simulate(SliderParams(), Inputs(drive_force=phi, excitation_amplitude=10.0 * ratio), 0.2)
    slips, sticks = result.event_counts["slip_start"], result.event_counts["stick"]
    if motion == NEVER_MOVES:
        assert slips == 0 and result.mean_velocity == 0.0
    elif motion == STICK_SLIP:
        assert slips == 10 and sticks == 10  # one slip in each of the 10 periods
    else:
        assert slips == 1 and sticks == 0  # slips from the start and never sticks
        assert math.copysign(1.0, result.mean_velocity) == math.copysign(1.0, phi)


@pytest.mark.parametrize(
    ("phi", "ratio", "words", "absent"),
    [
        ("0.7", "0.5", ("sticks and slips once a period", "0.643501 rad (A)", "2.87995 rad"), ("backwards",)),
        ("-0.7", "0.5", ("sticks and slips once a period", "backwards"), ()),
        ("0.2", "0.5", ("never moves", "a > 0.8"), ("phase",)),
        ("1.2", "0.5", ("slips all the time", "speeds up without bound"), ("phase", "rad")),
        ("1.6", "0.5", ("slips all the time", "at every phase"), ("rad",)),
    ],
)
def test_umap_point_says_what_the_slider_does(phi: str, ratio: str, words: tuple[str, ...],
                                              absent: tuple[str, ...]) -> None:
    done = run("umap", "--phi", phi, "--ratio", ratio)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == f"U({float(phi):g}, {float(ratio):g}) = {u_map(float(phi), float(ratio))!r}"
    for word in words:
        assert word in lines[1]
    for word in absent:
        assert word not in lines[1]


@pytest.mark.parametrize(("phi", "motion"), [("0.2", NEVER_MOVES), ("1.2", SLIPS_ALWAYS), ("1.0", SLIPS_ALWAYS)])
def test_umap_json_gives_no_slip_phase_where_there_is_no_periodic_slip(phi: str, motion: str) -> None:
    done = run("umap", "--phi", phi, "--ratio", "0.5", "--json")
    assert done.returncode == 0, done.stderr
    point = json.loads(done.stdout)
    assert point["motion"] == motion
    assert point["slip_start_phase"] is None and point["slip_phase_length"] is None


def test_help_gives_each_flag_its_range() -> None:
    done = run("umap", "--help")
    assert done.returncode == 0
    text = " ".join(done.stdout.split())
    assert "-1e+06 … 1e+06" in text and "2 … 2001" in text and "0 … 10" in text and "hops" in text
    assert "--landing-friction {impulsive,none}" in text and "impulsive | none; default impulsive" in text


def _console_scripts() -> list[str]:
    """The executables setup.py installs (read from its source: the one list of them)."""
    import ast

    tree = ast.parse((Path(__file__).resolve().parents[2] / "setup.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values):
                if isinstance(key, ast.Constant) and key.value == "console_scripts":
                    return [entry.split("=")[0].strip() for entry in ast.literal_eval(value)]
    raise AssertionError("setup.py declares no console_scripts")


@pytest.mark.parametrize("command", [*_console_scripts(), "python -m friction_sim"])
def test_every_installed_executable_answers_help_with_text_and_exit_0(command: str) -> None:
    """What a newcomer types first, as they type it: each installed script (the nodes
    included) and ``python -m friction_sim``, in a process of its own."""
    argv = [sys.executable, "-m", "friction_sim"] if command.startswith("python") else [
        str(Path(sys.executable).parent / command)]
    done = subprocess.run([*argv, "--help"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "usage:" in done.stdout and len(done.stdout.splitlines()) >= 3 and "Traceback" not in done.stderr
