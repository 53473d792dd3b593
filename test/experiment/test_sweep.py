"""Sweep files: the designs they expand to, and every kind of bad file refused
before any work, with the file, the line and the reason."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from friction_sim.core.model import spec
from friction_sim.core.model.params import Inputs, SliderParams, cos_degrees
from friction_sim.errors import ParameterError
from friction_sim.experiment.sweep import BLOCK, Distribution, SweepError, _draw, load_sweep, materialize, parse_sweep

CONFIG = Path(__file__).resolve().parents[2] / "config"

DESIGN = """\
name: design
settle_periods: 2
periods: 3
chunk_size: 5
seed: 11
fixed:
  mass: 2.0
grid:
  throw_number: {from: 0.5, to: 2.0, num: 4}
  excitation_angle: [30, 60]
points:
  - {track_inclination: 0}
  - {track_inclination: 5}
  - {track_inclination: -5}
samples: 7
random:
  mu: {distribution: normal, mean: 0.3, std: 0.2, low: 0.1, high: 0.45}
  static_ratio: {distribution: lognormal, median: 1.2, sigma: 0.3}
  excitation_phase: {distribution: uniform, low: -10, high: 10}
  landing_friction: {distribution: choice, values: [impulsive, none], weights: [3, 1]}
"""


def test_a_design_expands_to_grid_times_points_times_samples() -> None:
    sweep = parse_sweep(DESIGN)
    assert sweep.size == 4 * 2 * 3 * 7 and sweep.chunks == math.ceil(sweep.size / 5)
    assert sweep.slider_periods == sweep.size * 5
    columns = materialize(sweep, 0, sweep.size)
    assert np.array_equal(columns["point"], np.arange(sweep.size))
    # samples fastest, then the points entries, then the grid (last key fastest)
    assert np.array_equal(columns["track_inclination"][:21], np.repeat([0.0, 5.0, -5.0], 7))
    assert np.array_equal(columns["excitation_angle"][:42], np.repeat([30.0, 60.0], 21))
    assert np.array_equal(np.unique(columns["throw_number"]), np.linspace(0.5, 2.0, 4))
    assert np.all(columns["mass"] == 2.0) and np.all(columns["gravity"] == spec.GRAVITY.default)
    # the derived amplitude is Gamma m g cos(alpha), as core.model.dimensionless.throw_number reads it back
    for i in (0, 10, 30, 100, 167):
        params = SliderParams(mass=2.0, track_inclination=float(columns["track_inclination"][i]))
        expected = columns["throw_number"][i] * params.weight * cos_degrees(params.track_inclination)
        assert columns["excitation_amplitude"][i] == pytest.approx(expected, rel=1e-15)
    # truncation and ranges of the random columns
    assert columns["mu"].min() >= 0.1 and columns["mu"].max() <= 0.45
    assert columns["static_ratio"].min() >= 1.0
    assert np.all(np.abs(columns["excitation_phase"]) <= 10.0)
    assert set(columns["landing_friction"]) == {"impulsive", "none"}


def test_random_values_do_not_depend_on_the_chunking() -> None:
    sweep = parse_sweep(DESIGN.replace("samples: 7", f"samples: {BLOCK // 3}"))
    whole = materialize(sweep, 0, sweep.size)
    for start, stop in ((0, 1), (BLOCK - 3, BLOCK + 5), (2 * BLOCK + 17, 3 * BLOCK + 2), (sweep.size - 4, sweep.size)):
        part = materialize(sweep, start, stop)
        for name, values in whole.items():
            assert np.array_equal(values[start:stop], part[name]), (name, start, stop)
    again = materialize(parse_sweep(DESIGN.replace("samples: 7", f"samples: {BLOCK // 3}")), 0, 100)
    assert np.array_equal(again["mu"], whole["mu"][:100])
    other = materialize(parse_sweep(DESIGN.replace("seed: 11", "seed: 12")), 0, 100)
    assert not np.array_equal(other["mu"], materialize(parse_sweep(DESIGN), 0, 100)["mu"])


def test_distributions_have_their_moments() -> None:
    text = """\
periods: 1
samples: 40000
random:
  mu: {distribution: normal, mean: 0.3, std: 0.02}
  mass: {distribution: lognormal, median: 0.5, sigma: 0.2}
  excitation_angle: {distribution: uniform, low: 20, high: 60}
  landing_friction: {distribution: choice, values: [impulsive, none], weights: [0.8, 0.2]}
"""
    columns = materialize(parse_sweep(text), 0, 40000)
    assert columns["mu"].mean() == pytest.approx(0.3, abs=4 * 0.02 / 200)
    assert columns["mu"].std() == pytest.approx(0.02, rel=0.03)
    assert np.median(columns["mass"]) == pytest.approx(0.5, rel=0.01)
    assert np.log(columns["mass"]).std() == pytest.approx(0.2, rel=0.03)
    assert columns["excitation_angle"].mean() == pytest.approx(40.0, abs=0.2)
    assert np.mean(columns["landing_friction"] == "none") == pytest.approx(0.2, abs=0.01)


def test_a_lognormal_draw_is_libms_exp_of_its_normal_draw() -> None:
    """A lognormal column is math.exp (libm, as the core's) of the normal draws, not
    numpy's exp, which rounds differently with AVX-512 and between numpy versions
    (on NumPy 1.26.4 with AVX-512 it differs from libm in a quarter of the values):
    the same sweep samples the same points on every machine."""
    def stream() -> np.random.Generator:
        return np.random.Generator(np.random.PCG64(np.random.SeedSequence(5)))

    wide = {"low": -math.inf, "high": math.inf}
    normal = _draw(stream(), Distribution("normal", {"mean": math.log(0.5), "std": 0.2, **wide}), 500)
    lognormal = _draw(stream(), Distribution("lognormal", {"median": 0.5, "sigma": 0.2, **wide}), 500)
    assert lognormal.tolist() == [math.exp(v) for v in normal.tolist()]


def test_a_truncated_normal_stays_in_the_settings_range() -> None:
    columns = materialize(parse_sweep("periods: 1\nsamples: 5000\nrandom:\n"
                                      "  restitution: {distribution: normal, mean: 0.0, std: 0.5}\n"), 0, 5000)
    assert columns["restitution"].min() >= 0.0 and columns["restitution"].max() <= spec.RESTITUTION.high
    assert columns["restitution"].mean() > 0.2  # the lower half was redrawn, not clipped to 0
    assert np.sum(columns["restitution"] == 0.0) == 0


def test_a_list_and_fixed_values_and_drive_ratio() -> None:
    sweep = parse_sweep("periods: 4\nfixed: {mu: 0.2}\npoints:\n  - {drive_ratio: 0.5, mass: 1}\n"
                        "  - {drive_ratio: -0.25, mass: 3}\n")
    columns = materialize(sweep, 0, 2)
    assert sweep.size == 2 and sweep.settle_periods == 0
    assert list(columns["drive_force"]) == [0.5 * 0.2 * (1 * 10.0), -0.25 * 0.2 * (3 * 10.0)]  # phi mu (m g)


def test_the_shipped_sweeps_load() -> None:
    for path in sorted(CONFIG.glob("sweep_*.yaml")):
        sweep = load_sweep(path)
        assert sweep.size >= 1 and sweep.periods >= 1, path
    conveyor = load_sweep(CONFIG / "sweep_conveyor.yaml")
    assert set(conveyor.grid) >= {"throw_number", "excitation_angle"}
    assert set(np.unique(materialize(conveyor, 0, conveyor.size)["track_inclination"])) == {0.0, 5.0}


@pytest.mark.parametrize(("text", "line", "reason"), [
    ("periods: 5\nbogus: 1\n", 2, "unknown key 'bogus' in the sweep"),
    ("periods: 5\ninitial: cold\n", 2, "initial = 'cold' rejected: must be one of steady, rest"),
    ("periods: 5\ninitial: 1\n", 2, "initial = 1 rejected: must be a string"),
    ("settle_periods: 3\n", 1, "missing key 'periods'"),
    ("periods: 0\n", 1, "periods = 0 rejected: must be an integer in [1, 10000000]"),
    ("periods: 2.5\n", 1, "periods = 2.5 rejected"),
    ("periods: 5\nfixed:\n  mu: -0.1\n", 3, "mu = -0.1 rejected: must be in [1e-06, 10]"),
    ("periods: 5\nfixed:\n  speed: 1\n", 3, "unknown key 'speed' in fixed"),
    ("periods: 5\ngrid:\n  excitation_angle: [30, 95]\n", 3, "excitation_angle = 95.0 rejected"),
    ("periods: 5\ngrid:\n  mu: {from: 0.1, to: 0.3}\n", 3, "give a list, or from, to and num"),
    ("periods: 5\ngrid:\n  mu: []\n", 3, "an empty list"),
    ("periods: 5\ngrid:\n  landing_friction: [impulsive, sticky]\n", 3,
     "landing_friction = 'sticky' rejected: must be one of impulsive, none"),
    ("periods: 5\nfixed: {mass: 1}\ngrid:\n  mass: [1, 2]\n", 4, "sets mass, which 'mass' already sets"),
    ("periods: 5\nfixed: {excitation_amplitude: 1}\ngrid:\n  throw_number: [1, 2]\n", 4,
     "'throw_number' in grid sets excitation_amplitude"),
    ("periods: 5\nrandom:\n  mu: {distribution: normal, mean: 0.3, std: 0.1}\n", 3, "need 'samples'"),
    ("periods: 5\nsamples: 3\nrandom:\n  mu: {distribution: cauchy}\n", 4, "distribution = 'cauchy' rejected"),
    ("periods: 5\nsamples: 3\nrandom:\n  mu: {distribution: normal, mean: 0.3}\n", 4, "normal needs mean and std"),
    ("periods: 5\nsamples: 3\nrandom:\n  mu: {distribution: normal, mean: 0.3, std: 0.1, median: 1}\n", 4,
     "'median' is not a parameter of normal"),
    ("periods: 5\nsamples: 3\nrandom:\n  mu: {distribution: normal, mean: 50, std: 0.1}\n", 4,
     "of the normal distribution lies in [1e-06, 10]"),
    ("periods: 5\nsamples: 3\nrandom:\n  mu: {distribution: uniform, low: 0.5, high: 0.2}\n", 4, "must be below"),
    ("periods: 5\nsamples: 3\nrandom:\n  mu: {distribution: uniform, low: 0.1, high: 20}\n", 4,
     "mu = 20.0 rejected: must be in [1e-06, 10]"),
    ("periods: 5\nsamples: 3\nrandom:\n  landing_friction: {distribution: choice, values: [none, sticky]}\n", 4,
     "landing_friction = 'sticky' rejected"),
    ("periods: 5\nsamples: 3\nrandom:\n  mu: {distribution: choice, values: [0.1, 0.2], weights: [1]}\n", 4,
     "weights must be a list as long as values (2)"),
    ("periods: 5\npoints:\n  - {mu: 0.1}\n  - {mass: 2}\n", 4, "every points entry gives the same keys (mu)"),
    ("periods: 5\nfixed: {mass: 1000}\ngrid:\n  throw_number: [1, 200]\n", 4,
     "excitation_amplitude = 2000000.0 rejected: must be in [0, 1e+06] N (from throw_number = 200.0) at point 1"),
    ("periods: 5\ngrid:\n  throw_number: [1, 2]\n  excitation_angle:\n    - 30\n    - 0.01\n", 6,
     "excitation_angle = 0.01 rejected"),
    ("periods: 5\ngrid: {mu: [0.1, 0.2\n", 3, "not valid YAML"),
])
def test_a_bad_sweep_is_refused_with_its_line_and_reason(tmp_path: Path, text: str, line: int, reason: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(SweepError) as caught:
        load_sweep(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: line {line}: "), message
    assert reason in message, message
    assert "\n" not in message


def test_a_missing_file_and_a_non_mapping_are_refused(tmp_path: Path) -> None:
    with pytest.raises(SweepError, match="cannot read"):
        load_sweep(tmp_path / "nope.yaml")
    with pytest.raises(SweepError, match="a sweep is a mapping"):
        parse_sweep("- 1\n- 2\n", "list.yaml")


def test_a_chunk_size_override_is_checked() -> None:
    assert parse_sweep("periods: 2\n", chunk_size=3).chunk_size == 3
    with pytest.raises(SweepError, match="chunk_size = 0 rejected"):
        parse_sweep("periods: 2\n", chunk_size=0)


@pytest.mark.parametrize("setting", [spec.SETTLE_PERIODS, spec.PERIODS, spec.CHUNK_SIZE], ids=lambda s: s.name)
def test_the_averaging_windows_ranges_are_the_specs_everywhere(setting: spec.Setting,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    """settle_periods, periods and chunk_size have one range (core/model/spec.py): a sweep file,
    the command line (calibrate's window, sweep's --chunk-size) and the general mean speed
    take its bounds and refuse one beyond them with the same words."""
    from friction_sim.cli.main import build_parser
    from friction_sim.core.meanspeed.general import mean_speed

    assert setting.low is not None and setting.high is not None
    low, high = int(setting.low), int(setting.high)
    window = {"settle_periods": 0, "periods": 1, "chunk_size": 1}
    for good in (low, high):
        sweep = parse_sweep("\n".join(f"{key}: {good if key == setting.name else value}"
                                      for key, value in window.items()) + "\n")
        assert getattr(sweep, setting.name) == good
    command = ["calibrate", "m.csv", "--fit", "mu"] if setting.name != "chunk_size" else ["sweep", "s.yaml"]
    for bad in (low - 1, high + 1):
        with pytest.raises(SweepError) as caught:
            parse_sweep("\n".join(f"{key}: {bad if key == setting.name else value}"
                                  for key, value in window.items()) + "\n")
        words = str(caught.value).split("line ")[1].split(": ", 1)[1]
        assert words == f"{setting.name} = {bad} rejected: must be an integer in [{low}, {high}] {setting.unit}"
        with pytest.raises(SystemExit):
            build_parser().parse_args([*command, setting.option, str(bad)])
        assert words in capsys.readouterr().err
        if setting.name != "chunk_size":
            with pytest.raises(ParameterError, match=re.escape(words)):
                mean_speed(SliderParams(), Inputs(drive_force=0.2, excitation_amplitude=5.0), simulate=True,
                           **{"settle_periods": 1, "periods": 1, setting.name: bad})
