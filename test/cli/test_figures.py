"""The figures as a reader sees them: drawn with Agg and measured in display
coordinates (legend against curves, labels against their axes, the U map
against its axes), their text read back, and the saved files' resolution."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import QuadMesh
from matplotlib.figure import Figure
from matplotlib.text import Text
from PIL import Image

from friction_sim.cli.experiments import write_report
from friction_sim.cli.figures import (
    FIGURE_DPI,
    conveyor_figure,
    save_figure,
    trace_data,
    trace_figure,
    u_map_figure,
)
from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.conveyor import conveyor_sweep
from friction_sim.core.meanspeed.urelation import u_grid
from friction_sim.core.model.commands import Command
from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.model.events import EventKind
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.exciter import steady_response
from friction_sim.core.runtime.simulation import SimulationResult, simulate
from friction_sim.experiment.report import RunData

#: Drive force and amplitude (m = 1 kg, mu = 0.1, g = 10 m/s^2): the paper's
#: case, backwards, a short slip, slipping all the time, and standing still.
CASES = {
    "paper": (0.7, 5.0),
    "backwards": (-0.7, 5.0),
    "short slip": (0.05, 9.9),
    "slips always": (1.2, 5.0),
    "never moves": (0.3, 5.0),
    "hops": (0.3, 20.0),  # Gamma = 2: one flight a period
}


def trace_of(drive: float, amplitude: float, periods: float = 2.5) -> SimulationResult:
    inputs = Inputs(drive_force=drive, excitation_amplitude=amplitude)
    f = inputs.excitation_frequency
    return simulate(SliderParams(), inputs, periods / f, sample_rate=2000.0 * f)


def drawn(figure: Figure) -> Any:
    """Draw ``figure`` with Agg (as savefig does) and return the renderer."""
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return canvas.get_renderer()


def display_points(line: Any) -> np.ndarray:
    return np.asarray(line.get_transform().transform(np.column_stack(line.get_data())))


@pytest.fixture(scope="module", params=list(CASES), ids=list(CASES))
def fig2(request: pytest.FixtureRequest) -> tuple[SimulationResult, Figure, Any]:
    result = trace_of(*CASES[request.param])
    figure = trace_figure(result)
    return result, figure, drawn(figure)


def test_the_legend_leaves_every_force_curve_visible(fig2: tuple[SimulationResult, Figure, Any]) -> None:
    _, figure, renderer = fig2
    force = figure.axes[0]
    legend = force.get_legend().get_window_extent(renderer)
    limit = next(line for line in force.get_lines() if "R" in line.get_label())
    peak = display_points(limit)[np.argmax(limit.get_ydata())]
    assert not legend.contains(*peak), f"the legend covers the mu R peak at {peak}"
    for line in force.get_lines():
        covered = legend.count_contains(display_points(line))
        assert covered == 0, f"the legend covers {covered} points of {line.get_label()!r}"
    assert figure.bbox.contains(legend.x0, legend.y0) and figure.bbox.contains(legend.x1, legend.y1)


def test_point_labels_sit_inside_the_velocity_axes(fig2: tuple[SimulationResult, Figure, Any]) -> None:
    _, figure, renderer = fig2
    speed = figure.axes[2]
    frame = speed.get_window_extent(renderer)
    labels = [text for text in speed.texts if text.get_text() in "ABC"]
    for text in labels:
        box = text.get_window_extent(renderer)
        assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1, \
            f"label {text.get_text()} at {box.bounds} leaves the axes {frame.bounds}"


def test_the_paper_case_marks_every_a_b_and_c() -> None:
    figure = trace_figure(trace_of(*CASES["paper"]))
    labels = sorted(text.get_text() for text in figure.axes[2].texts)
    assert labels == ["A"] * 3 + ["B"] * 3 + ["C"] * 2  # 2.5 periods: the third slip is cut off


@pytest.mark.parametrize("case", ["paper", "backwards", "short slip", "slips always"])
def test_b_marks_the_fastest_instant_of_each_period(case: str) -> None:
    result = trace_of(*CASES[case], periods=3.0)
    figure = trace_figure(result)
    traj = result.trajectory
    assert traj is not None
    marks = [text.xy for text in figure.axes[2].texts if text.get_text() == "B"]
    assert len(marks) == 3, "one B per period"
    for t_ms, _ in marks:
        t = t_ms * 1e-3
        after = int(np.searchsorted(traj.t, t, side="right"))
        before = after - 1
        way = np.sign(traj.v[after])
        assert traj.mode[before] != 0 and traj.mode[after] != 0, f"B at {t} s is not in a slip"
        # The speed peaks: the acceleration along the slip changes sign from + to - at B.
        assert way * traj.acceleration[before] > 0.0 > way * traj.acceleration[after], f"B at {t} s is no peak"


def figure_text(figure: Figure) -> list[str]:
    return [text.get_text() for text in figure.findobj(Text) if text.get_text()]


def spelled_out_greek(texts: list[str]) -> list[str]:
    """Texts with mu or phi written out (not the mathtext commands \\mu, \\varphi)."""
    return [text for text in texts if re.search(r"(?<!\\)\b(mu|phi)\b", text)]


def report_data() -> RunData:
    params, inputs = SliderParams(), Inputs()
    return RunData(
        params=params, inputs=inputs, duration=2.0, name="steps",
        schedule=[Command(1.0, "excitation_amplitude", {"excitation_amplitude": 6.0})],
        mean_velocity=[(0.02 * k, 2e-4 if k < 50 else 4e-4) for k in range(1, 100)],
    )


def test_no_label_spells_out_greek_letters(tmp_path: Path) -> None:
    trace_texts = figure_text(trace_figure(trace_of(*CASES["paper"])))
    umap_texts = figure_text(u_map_figure(u_grid(11)))
    assert any(r"\mu" in text for text in trace_texts) and any(r"\mu" in text for text in umap_texts)
    assert any(r"\varphi" in text for text in umap_texts)
    from friction_sim.cli.figures import report_figure
    from friction_sim.experiment.report import build_report

    data = report_data()
    report_texts = figure_text(report_figure(data, build_report(data)))
    for texts in (trace_texts, umap_texts, report_texts):
        assert spelled_out_greek(texts) == []


def test_the_u_map_cells_cover_the_whole_axes() -> None:
    figure = u_map_figure(u_grid(11))  # coarse: a missing half cell would be a wide strip
    ax = figure.axes[0]
    mesh = next(artist for artist in ax.collections if isinstance(artist, QuadMesh))
    corners = mesh.get_coordinates()
    assert (corners[..., 0].min(), corners[..., 0].max()) == ax.get_xlim() == (0.0, 1.0)
    assert (corners[..., 1].min(), corners[..., 1].max()) == ax.get_ylim() == (0.0, 1.0)
    # And as drawn (at the saved resolution): the pixels just inside the frame are map, not background.
    figure.set_dpi(FIGURE_DPI)
    box = ax.get_window_extent(drawn(figure))
    pixels = np.asarray(figure.canvas.buffer_rgba())[..., :3].astype(int)
    height = pixels.shape[0]
    left, right = math.ceil(box.x0) + 2, math.floor(box.x1) - 3
    top, bottom = height - math.floor(box.y1) + 2, height - math.ceil(box.y0) - 3
    edges = {"left": pixels[top:bottom, left], "right": pixels[top:bottom, right],
             "top": pixels[top, left:right], "bottom": pixels[bottom, left:right]}
    for side, strip in edges.items():
        white = np.all(strip >= 250, axis=-1)
        assert not white.any(), f"{white.sum()} background pixels along the {side} edge of the map"


def saved_dpi(path: Path) -> tuple[float, float]:
    dpi = Image.open(path).info.get("dpi", (0.0, 0.0))
    return float(dpi[0]), float(dpi[1])


def test_every_figure_is_saved_at_150_dpi_or_more(tmp_path: Path) -> None:
    assert FIGURE_DPI >= 150
    figure = trace_figure(trace_of(*CASES["paper"]))
    path = save_figure(figure, tmp_path / "deeper" / "fig2.png")
    width, height = figure.get_size_inches()
    assert Image.open(path).size == (round(width * FIGURE_DPI), round(height * FIGURE_DPI))
    _, _, picture = write_report(report_data(), tmp_path / "report", "steps")
    for saved in (path, picture):  # PNG keeps pixels per metre: 150 dpi reads back as 150.01
        assert min(saved_dpi(saved)) == pytest.approx(FIGURE_DPI, abs=0.05)


def test_only_save_figure_writes_pictures_in_the_cli_modules_here() -> None:
    """The modules of this test's scope save through save_figure (one resolution)."""
    package = Path(__file__).resolve().parents[2] / "friction_sim" / "cli"
    for path in package.glob("*.py"):
        if path.name != "figures.py":
            assert "savefig(" not in path.read_text(), f"{path.name} calls savefig itself"
    assert (package / "figures.py").read_text().count("savefig(") == 1


@pytest.mark.parametrize(("params", "drive", "amplitude"), [
    (SliderParams(), 0.3, 20.0),  # normal excitation, Gamma = 2
    (SliderParams(mu=0.5, excitation_angle=30.0), 0.0, 20.0),  # inclined, the conveyor's case
    (SliderParams(mu=0.3, excitation_angle=60.0, track_inclination=5.0, static_ratio=1.3), 0.0, 15.0),
])
def test_a_flight_gets_a_height_panel_with_every_lift_off_and_landing(params: SliderParams, drive: float,
                                                                      amplitude: float) -> None:
    inputs = Inputs(drive_force=drive, excitation_amplitude=amplitude)
    result = simulate(params, inputs, 3.0 / inputs.excitation_frequency, sample_rate=2000.0 * 50.0)
    traj = result.trajectory
    assert traj is not None and traj.z.max() > 0.0
    figure = trace_figure(result)
    assert len(figure.axes) == 5
    height = figure.axes[4]
    assert "height z" in height.get_ylabel()
    curve = height.get_lines()[0]
    np.testing.assert_array_equal(curve.get_ydata(), traj.z * 1e6)
    inside = [e for e in result.events if e.t <= traj.t[-1]]
    for kind, marker in ((EventKind.LIFT_OFF, "^"), (EventKind.LANDING, "v")):
        marked = sorted(float(line.get_xdata()[0]) for line in height.get_lines() if line.get_marker() == marker)
        assert marked == [e.t * 1e3 for e in inside if e.kind is kind] and len(marked) >= 2
    assert any(r"\Gamma" in text for text in figure_text(figure))


def test_a_run_on_the_track_keeps_the_four_panels() -> None:
    assert len(trace_figure(trace_of(*CASES["paper"])).axes) == 4
    # an inclined vibration below lift-off: Ft varies, still four panels
    result = simulate(SliderParams(excitation_angle=60.0), Inputs(drive_force=0.0, excitation_amplitude=8.0),
                      2.0 / 50.0, sample_rate=100_000.0)
    assert result.flight_fraction == 0.0 and len(trace_figure(result).axes) == 4


def test_the_conveyor_figure_marks_gammas_peaks_reversal_and_irregular_points() -> None:
    sweep = conveyor_sweep(21, 9)
    figure = conveyor_figure(sweep)
    top, bottom = figure.axes
    vertical = sorted({float(line.get_xdata()[0]) for line in top.get_lines()
                       if len(line.get_xdata()) == 2 and line.get_xdata()[0] == line.get_xdata()[1]})
    assert vertical == [1.0, 3.30]
    texts = figure_text(figure)
    assert any(r"\Gamma = 1$" in t for t in texts) and any(r"\Gamma = 3.30$" in t for t in texts)
    stars = [line for line in top.get_lines() if line.get_marker() == "*" and len(line.get_xdata()) == 1]
    assert sorted((float(s.get_xdata()[0]), float(s.get_ydata()[0])) for s in stars) == sorted(
        (p.throw_number, p.u) for p in sweep.peaks.values())
    hollow = sum(len(line.get_xdata()) for axis in (top, bottom) for line in axis.get_lines()
                 if line.get_marker() == "o" and line.get_markerfacecolor() == "none" and len(line.get_xdata()))
    irregular = sum(int(np.sum(~c.periodic)) for c in (*sweep.gamma_curves.values(), sweep.slope))
    assert hollow == irregular
    assert sweep.reversal is not None
    assert any(float(line.get_xdata()[0]) == sweep.reversal for line in bottom.get_lines())
    assert spelled_out_greek(texts) == []


#: A resonant feeder driven at its natural frequency: the slideway's vibration lags the drive by
#: a quarter period (drive level 0.5 gives 5 m/s^2 there, the paper's Pa = 5 N on 1 kg).
RESONANT = SliderParams(actuator="resonant", natural_frequency=50.0, damping_ratio=0.02, full_drive_acceleration=10.0)


@pytest.mark.parametrize("params", [SliderParams(), RESONANT], ids=["default", "resonant"])
def test_the_trace_plots_the_single_sliders_path(params: SliderParams) -> None:
    """What the trace plots (trace_data) is the single slider's motion, state by state,
    and B sits where mu R rises back through |Ft| with the contact force as the slider
    feels it: for the resonant plant a quarter period after the drive's own phase."""
    inputs = Inputs(drive_force=0.7)
    f = inputs.excitation_frequency
    spacing = 1.0 / (2000.0 * f)
    result = simulate(params, inputs, 3.0 / f, sample_rate=1.0 / spacing)
    data = trace_data(result)
    slider = Slider(params, inputs)
    states = []
    for t in data.t:
        slider.advance_to(float(t))
        states.append(slider.state())

    def column(name: str) -> np.ndarray:
        return np.array([getattr(state, name) for state in states])

    def same(drawn: np.ndarray, exact: np.ndarray) -> None:  # numpy's sin against libm's: the last bits
        np.testing.assert_allclose(drawn, exact, rtol=1e-12, atol=1e-12 * float(np.max(np.abs(exact))))

    for drawn, name in ((data.x, "x"), (data.v, "v"), (data.acceleration, "acceleration")):
        same(drawn, column(name))
    same(data.friction_limit, params.mu * column("normal_force"))
    same(data.friction, np.abs(column("friction_force")))
    same(data.applied, params.mass * column("acceleration") - column("friction_force"))
    np.testing.assert_allclose(data.applied, inputs.drive_force, rtol=1e-12)  # beta = 90: Ft is Fd
    assert data.steady_force

    amplitude, lag = (steady_response(inputs.drive_level, params.full_drive_acceleration, f,
                                      params.natural_frequency, params.damping_ratio) if params.resonant
                      else (inputs.excitation_amplitude / params.mass, 0.0))
    assert lag == pytest.approx(math.pi / 2 if params.resonant else 0.0, abs=1e-12)
    e = (params.weight - inputs.drive_force / params.mu) / (params.mass * amplitude)
    fastest = [(math.pi - math.asin(e) + lag) / (TWO_PI * f) + k / f for k in range(3)]
    marks = [(t, v) for label, t, v in data.points if label == "B"]
    np.testing.assert_allclose([t for t, _ in marks], fastest, rtol=0.0, atol=1e-3 * spacing)
    # The speed at B is read off the samples linearly: below the peak by at most spacing^2/8 |dv'/dt|
    # (the acceleration's rate around B, inside the slip).
    for (t, v), exact in zip(marks, fastest):
        k = int(np.searchsorted(data.t, t))
        jerk = float(np.max(np.abs(np.diff(data.acceleration[k - 3:k + 3])))) / spacing
        assert 0.0 <= slider_speed(params, inputs, exact) - v <= spacing**2 / 8.0 * jerk, (t, v)

    figure = trace_figure(result)
    force, speed = figure.axes[0], figure.axes[2]
    drawn = {line.get_label(): line.get_ydata() for line in force.get_lines()}
    np.testing.assert_array_equal(drawn[r"$\mu R$ (friction limit)"], data.friction_limit)
    np.testing.assert_array_equal(drawn[r"$|F_f|$ (friction force)"], data.friction)
    np.testing.assert_array_equal(drawn[r"$F_d$ (drive force)"], np.abs(data.applied))
    np.testing.assert_array_equal(speed.get_lines()[0].get_ydata(), data.v * 1e3)
    assert [text.xy for text in speed.texts if text.get_text() == "B"] == [(t * 1e3, v * 1e3) for t, v in marks]


def slider_speed(params: SliderParams, inputs: Inputs, t: float) -> float:
    slider = Slider(params, inputs)
    slider.advance_to(t)
    return slider.state().v


def test_the_report_picture_shows_a_resonant_plant_by_drive_level_and_slideway_amplitude() -> None:
    from friction_sim.cli.figures import input_panels, report_figure
    from friction_sim.core.physics.plant import steady_excitation
    from friction_sim.experiment.report import build_report

    params = SliderParams(actuator="resonant", natural_frequency=52.0)
    data = RunData(params=params, inputs=Inputs(drive_level=0.4), duration=2.0, name="resonant steps",
                   schedule=[Command(1.0, "drive_level", {"drive_level": 0.7})],
                   commands=[Command(1.0, "drive_level", {"drive_level": 0.7})],
                   mean_velocity=[(0.02 * k, 2e-4 if k < 50 else 4e-4) for k in range(1, 100)])
    panels = {label: (times, values) for label, times, values in input_panels(data)}
    assert list(panels) == ["drive level u", "slideway [m/s$^2$]", "Fd [N]", "f [Hz]"]
    assert panels["drive level u"] == ([0.0, 1.0, 2.0], [0.4, 0.7, 0.7])
    slideway = [steady_excitation(params, Inputs(drive_level=u))[0] / params.mass for u in (0.4, 0.7, 0.7)]
    assert panels["slideway [m/s$^2$]"][1] == slideway and slideway[1] > slideway[0] > 0.0
    labels = [axis.get_ylabel() for axis in report_figure(data, build_report(data)).axes]
    assert labels[1:] == list(panels) and not any("Pa" in label for label in labels)
    # the force actuator keeps its Pa
    assert [label for label, _, _ in input_panels(report_data())] == ["Pa [N]", "Fd [N]", "f [Hz]"]
