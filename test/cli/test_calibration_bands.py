"""The calibrated plant's 95 % band drawn on the conveyor figure (issue 31, item 5):
``friction-sim conveyor --params calibrated.yaml``.  The band is checked in the
figure's data (the filled region's vertices and the curve's points), not in pixels."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from friction_sim.cli.conveyor import calibrated_bands, draw_bands, suptitle_text
from friction_sim.cli.figures import conveyor_figure
from friction_sim.core.meanspeed.conveyor import conveyor_sweep
from friction_sim.experiment.calibration import FitOptions, calibrate
from friction_sim.experiment.calibration_predict import read_calibrated
from friction_sim.experiment.measurements import read_measurements

BIN = Path(sys.executable).parent
EXAMPLE = Path(__file__).resolve().parents[2] / "config" / "calibration_example.csv"
WINDOW = {"settle_periods": 30, "periods": 30}


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shipped example's calibration (mu and mu_s/mu, the paper's 90 degree plant)."""
    result = calibrate(read_measurements(EXAMPLE), {}, FitOptions(fit=("mu", "static_ratio"), **WINDOW))
    path = tmp_path_factory.mktemp("calibrated") / "calibrated.yaml"
    path.write_text(result.parameters_file())
    return path


def test_the_conveyor_figure_draws_the_calibrated_band_in_both_panels(calibrated: Path) -> None:
    """Each panel gets a twin axis whose filled region runs along the band's low and
    high ends [mm/s] and whose curve is the speed at the estimates, inside the band."""
    sweep = conveyor_sweep(11, 5)
    bands = calibrated_bands(read_calibrated(calibrated), sweep, 7, {"drive_force": 0.9}, samples=60,
                             window=WINDOW)
    assert [(band.panel, band.name) for band in bands] == [(0, "throw_number"), (1, "track_inclination")]
    figure = draw_bands(conveyor_figure(sweep), bands, str(calibrated))
    assert len(figure.axes) == 4  # the two panels and a speed axis each
    for band, axes in zip(bands, figure.axes[2:]):
        p = band.prediction
        # Where the speed does not depend on the calibrated parameters the band has no width, and the
        # estimates' speed and the samples' percentiles differ by rounding alone: of a mean speed taken
        # from positions summed over the window's periods, two events a period, each one rounding of x.
        slack = 2 * (WINDOW["settle_periods"] + WINDOW["periods"]) * np.finfo(float).eps * np.abs(p.speed)
        assert np.all(p.low <= p.speed + slack) and np.all(p.speed <= p.high + slack) and np.any(p.high > p.low)
        (filled,) = axes.collections
        corners = np.vstack([path.vertices for path in filled.get_paths()])
        for x, low, high in zip(band.x, p.low * 1e3, p.high * 1e3):
            at = corners[np.isclose(corners[:, 0], x)][:, 1]
            assert at.min() == pytest.approx(low) and at.max() == pytest.approx(high)
        (curve,) = axes.lines
        assert np.array_equal(curve.get_xdata(), band.x) and np.array_equal(curve.get_ydata(), p.speed * 1e3)
    assert "calibrated" in suptitle_text(figure)


def test_a_fitted_or_given_axis_gets_no_band(calibrated: Path) -> None:
    sweep = conveyor_sweep(11, 5)
    bands = calibrated_bands(read_calibrated(calibrated), sweep, 5, {"track_inclination": 2.0}, samples=20,
                             window=WINDOW)
    assert [band.name for band in bands] == ["throw_number"]


def test_the_command_draws_the_band(calibrated: Path, tmp_path: Path) -> None:
    done = subprocess.run([str(BIN / "friction-sim"), "conveyor", "--png", str(tmp_path / "c.png"), "--points", "11",
                           "--slope-points", "5", "--params", str(calibrated), "--set", "drive_force=0.9",
                           "--band-points", "5", "--band-samples", "40"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("the 95 % band of 40 parameter sets") == 2
    assert (tmp_path / "c.png").stat().st_size > 10_000
    refused = subprocess.run([str(BIN / "friction-sim"), "conveyor", "--png", str(tmp_path / "d.png"), "--points",
                              "11", "--params", str(calibrated), "--set", "mu=0.2"], capture_output=True, text=True,
                             timeout=300)
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1 and "mu is calibrated" in refused.stderr


SWEEP = """\
name: calibrated
settle_periods: 30
periods: 30
plant_params: {params}
fixed: {{drive_force: 0.9}}
grid:
  excitation_amplitude: [5.0, 6.5, 8.0]
  excitation_frequency: [40.0, 50.0]
"""


def test_a_sweep_of_a_calibrated_plant_reports_its_band(calibrated: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """``sweep-report`` of a sweep whose plant_params is a calibrated.yaml: each cell's
    band is predict's at the cell's settings (over the sweep's periods), holds the
    sweep's own speed at the estimates, and its width is the figure's extra map."""
    from friction_sim.cli.main import main
    from friction_sim.cli.sweep_figure import sweep_figure
    from friction_sim.experiment.calibration_bands import sweep_bands
    from friction_sim.experiment.calibration_predict import predict
    from friction_sim.experiment.sweep_report import build_maps

    (tmp_path / "s.yaml").write_text(SWEEP.format(params=calibrated))
    output = tmp_path / "s.parquet"
    assert main(["sweep", str(tmp_path / "s.yaml"), "--output", str(output), "--workers", "0"]) == 0
    maps = build_maps(output, "excitation_amplitude", "excitation_frequency")
    bands, said = sweep_bands(maps, samples=60)
    assert bands is not None and "calibrated in" in said and bands.names == ("mu", "static_ratio")
    (low,), (high,), (mean,) = bands.low, bands.high, (maps.slices[0].mean,)
    assert low.shape == high.shape == mean.shape == (2, 3)
    assert np.all(low <= mean) and np.all(mean <= high) and np.all(high > low)
    at = predict(read_calibrated(calibrated), {"drive_force": 0.9, "excitation_amplitude": 6.5,
                                               "excitation_frequency": 40.0}, samples=60, settle_periods=30,
                 periods=30)
    assert (low[0, 1], high[0, 1]) == (at.low[0], at.high[0])
    figure = sweep_figure(maps, bands)
    (widths,) = [mesh for axes in figure.axes for mesh in axes.collections
                 if "band" in axes.get_title() and hasattr(mesh, "get_array") and mesh.get_array() is not None
                 and np.size(mesh.get_array()) == 6]
    assert np.allclose(np.asarray(widths.get_array()).reshape(2, 3), (high - low) * 1e3)
    code = main(["sweep-report", str(output), "--x", "excitation_amplitude", "--y", "excitation_frequency",
                 "--output", str(tmp_path / "report")])
    assert code == 0 and "the 95 % band of the plant calibrated in" in capsys.readouterr().out
