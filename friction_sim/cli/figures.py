"""Pictures of the paper's figures.  Each function takes result objects and
returns a matplotlib Figure; matplotlib is imported only when one is drawn,
so the core and the nodes never pay for it.

* :func:`u_map_figure` is the paper's Fig. 3: U over (Fd/FfN, Pa/Q).
* :func:`trace_figure` is the paper's Fig. 2: forces with the impulse areas,
  acceleration, velocity and displacement, with the points A, B, C; what it
  plots, :func:`trace_data`, comes from the sampled path alone.
* :func:`conveyor_figure` is the general model's conveying figure: U
  against the throw number for several vibration angles, and against the
  track inclination (``friction-sim conveyor``).
* :func:`tuning_figure` is a resonant feeder's tuning curve (``friction-sim
  resonance``): amplitude, lag and mean speed against the drive frequency.
* :func:`reduction_figure` is the paper's Fig. 4 claim (``friction-sim
  reduction``): the apparent friction against the mean speed and Pa/Q.
* :func:`calibration_figure` is a calibration's check (``friction-sim
  calibrate``): measured against fitted mean speed.
* :func:`report_figure` is an experiment report's picture: target and
  measured mean speed, Pa, Fd and f against time.

Every picture is written by :func:`save_figure`, at :data:`FIGURE_DPI`.
Labels use mathtext (``$\\mu R$``), never spelled-out Greek.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from friction_sim.core.meanspeed.urelation import UMap
from friction_sim.core.model.events import EventKind, Mode
from friction_sim.core.model.params import Inputs
from friction_sim.core.physics.plant import slideway_amplitude
from friction_sim.core.runtime.simulation import SimulationResult
from friction_sim.experiment.report import RunData, SegmentRow, inputs_at

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from friction_sim.core.meanspeed.conveyor import ConveyorSweep
    from friction_sim.core.meanspeed.reduction import ReductionCurves
    from friction_sim.core.meanspeed.tuning import TuningCurve
    from friction_sim.experiment.calibration import Calibration
    from friction_sim.experiment.calibration_run import RunCalibration


#: The resolution of every saved figure [dots per inch]: print quality, and
#: fine hatching and thin lines stay legible when zoomed.
FIGURE_DPI = 150


def save_figure(figure: Figure, path: Path) -> Path:
    """Write ``figure`` to ``path`` (its format from the suffix) at
    :data:`FIGURE_DPI`, creating the folder; return the path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=FIGURE_DPI)
    return path


def save_outputs(lines: Sequence[str], png: Path, csv: Path | None, write_table: Callable[[Path], Path],
                 draw: Callable[[], Figure]) -> int:
    """What a figure command ends with: print ``lines`` (what the figure shows),
    write the table (to ``csv``, default beside the PNG) and the picture; exit code 0."""
    for line in lines:
        print(line)
    print(f"wrote {write_table(csv if csv is not None else png.with_suffix('.csv'))}")
    print(f"wrote {save_figure(draw(), png)}")
    return 0


def pyplot_free_figure(**kwargs: object) -> Figure:
    """A Figure not registered with pyplot (no GUI backend, no global state)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)  # type: ignore[arg-type]


def u_map_figure(umap: UMap) -> Figure:
    """U as coloured cells and contours over phi = Fd/FfN (x) and a = Pa/Q (y),
    the no-motion region hatched and its boundary phi = 1 - a drawn.  Each grid
    value fills the cell around it, out to the edges of the domain [0, 1]^2,
    so the map covers the whole axes."""
    fig = pyplot_free_figure(figsize=(7.0, 5.6), layout="constrained")
    ax = fig.add_subplot()
    u = np.where(np.isfinite(umap.u), umap.u, np.nan)
    phi_edges, a_edges = _cell_edges(umap.phi), _cell_edges(umap.amplitude_ratio)
    cells = ax.pcolormesh(phi_edges, a_edges, u, shading="flat", cmap="viridis", rasterized=True)
    phi, a = np.meshgrid(umap.phi, umap.amplitude_ratio)
    steps = np.array([0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5])
    levels = steps[steps < np.nanmax(u)]
    lines = ax.contour(phi, a, u, levels=levels, colors="white", linewidths=0.7)
    ax.clabel(lines, fmt="%g", fontsize=7)
    boundary = np.linspace(0.0, 1.0, 200)
    ax.fill_between(boundary, 0.0, 1.0 - boundary, facecolor="none", hatch="//",
                    edgecolor="0.4", linewidth=0.0, label="no motion ($U = 0$)")
    ax.plot(boundary, 1.0 - boundary, color="red", linewidth=1.5, label=r"boundary $\varphi = 1 - a$")
    ax.set_xlim(phi_edges[0], phi_edges[-1])
    ax.set_ylim(a_edges[0], a_edges[-1])
    ax.set_xlabel(r"$F_d / F_{fN}$   ($\varphi = F_d / (\mu m g)$)")
    ax.set_ylabel(r"$P_a / Q$   ($a = P_a / (m g)$)")
    ax.set_title(r"Nondimensional mean speed $U = V f / (g \mu)$")
    ax.legend(loc="lower left", fontsize=8)
    fig.colorbar(cells, ax=ax, label="$U$")
    return fig


def _cell_edges(centres: np.ndarray) -> np.ndarray:
    """Edges of the cells around sorted grid values: midway between neighbours,
    and the outer cells reach the domain [0, 1] (or the values, if beyond it)."""
    centres = np.asarray(centres, float)
    middle = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate(([min(0.0, centres[0])], middle, [max(1.0, centres[-1])]))


@dataclass(frozen=True)
class TraceData:
    """What :func:`trace_figure` draws, in SI units, all of it from the sampled path
    (:meth:`Slider.sample <friction_sim.core.engine.single.Slider.sample>`, through
    :func:`~friction_sim.core.runtime.simulation.simulate`) and its events: nothing
    here restates a force law, so a resonant plant (whose excitation lags its drive)
    is drawn as the slider moved.

    ``applied`` is the applied tangential force Ft = m a - Ff at each sample (Newton's
    law on the sampled acceleration and friction: the drive force, the slope's pull and
    a tangential excitation together, with whatever lag the exciter has);
    ``friction_limit`` mu R and ``friction`` |Ff| with the sampled contact force;
    ``accelerating`` and ``decelerating`` the slipping samples where the applied force
    along the slip is above or below |Ff|; ``points`` the marks (label, t [s], v [m/s]):
    A where a slip starts, B where the speed peaks in it, C where it sticks.
    """

    t: np.ndarray
    applied: np.ndarray
    friction_limit: np.ndarray
    friction: np.ndarray
    accelerating: np.ndarray
    decelerating: np.ndarray
    acceleration: np.ndarray
    v: np.ndarray
    x: np.ndarray
    z: np.ndarray
    points: tuple[tuple[str, float, float], ...]
    #: Ft is constant along the run (no tangential excitation): drawn as the drive force.
    steady_force: bool
    #: The run leaves the track within its samples (the height gets a panel).
    flies: bool


def trace_data(result: SimulationResult) -> TraceData:
    """The arrays :func:`trace_figure` plots for a sampled simulation (``sample_rate`` set)."""
    traj = result.trajectory
    if traj is None:
        raise ValueError("trace_figure needs a SimulationResult with a sampled trajectory")
    applied = result.params.mass * traj.acceleration - traj.friction_force
    friction = np.abs(traj.friction_force)
    slipping = (traj.mode == Mode.FORWARD) | (traj.mode == Mode.BACKWARD)
    along = np.sign(traj.v) * applied  # the applied force along the slip: above |Ff| it speeds the slider up
    p, i = result.params, result.inputs
    steady = p.tangential_ratio == 0.0 or (i.excitation_amplitude == 0.0 and not p.resonant)
    return TraceData(
        t=traj.t, applied=applied, friction_limit=result.params.mu * traj.normal_force, friction=friction,
        accelerating=slipping & (along >= friction), decelerating=slipping & (along < friction),
        acceleration=traj.acceleration, v=traj.v, x=traj.x, z=traj.z, points=_points(result),
        steady_force=steady, flies=flies(result))


def trace_figure(result: SimulationResult) -> Figure:
    """The paper's Fig. 2 from a sampled simulation (``sample_rate`` set): the
    arrays of :func:`trace_data`.

    The force panel's legend sits above the panel, clear of every curve; the
    velocity panel keeps headroom so the labels of A, B and C stay inside it.
    A run that leaves the track gets a fifth panel, the height z above the
    track, with every lift-off and landing marked (and the drawn tangential
    force is the whole applied Ft(t) wherever it varies: an inclined
    vibration or a slope)."""
    data = trace_data(result)
    t_ms = data.t * 1e3
    drive = np.abs(data.applied)  # magnitudes along the slip: with Ft < 0 everything mirrors
    if data.steady_force:
        drive_label = (r"$F_d$ (drive force)" if result.inputs.tangential_force >= 0.0
                       else r"$|F_d|$ (drive force)")
    else:
        drive_label = r"$|F_t|$ (applied tangential force)"

    fig = pyplot_free_figure(figsize=(8.0, 11.5 if data.flies else 9.5), layout="constrained")
    axes = fig.subplots(5 if data.flies else 4, 1, sharex=True)
    ax = axes[0]
    ax.plot(t_ms, data.friction_limit, color="tab:blue", linestyle="--", label=r"$\mu R$ (friction limit)")
    ax.plot(t_ms, data.friction, color="tab:red", linewidth=2.2, label=r"$|F_f|$ (friction force)")
    ax.plot(t_ms, drive, color="black", linewidth=1.0, label=drive_label)
    ax.fill_between(t_ms, drive, data.friction, where=data.accelerating,
                    facecolor="none", hatch="///", edgecolor="tab:green", label="impulse accelerating")
    ax.fill_between(t_ms, drive, data.friction, where=data.decelerating,
                    facecolor="none", hatch="\\\\\\", edgecolor="tab:orange", label="impulse decelerating")
    ax.set_ylabel("force [N]")
    ax.legend(loc="lower left", bbox_to_anchor=(0.0, 1.02, 1.0, 0.1), mode="expand", borderaxespad=0.0,
              ncol=3, fontsize=8, frameon=False)
    panels = [(axes[1], data.acceleration, "acceleration [m/s²]"), (axes[2], data.v * 1e3, "velocity [mm/s]"),
              (axes[3], data.x * 1e6, "displacement [µm]")]
    if data.flies:
        panels.append((axes[4], data.z * 1e6, "height z [µm]"))
    for axis, values, label in panels:
        axis.plot(t_ms, values, color="black", linewidth=1.0)
        axis.set_ylabel(label)
    for axis in axes:
        axis.grid(alpha=0.3)
    axes[2].set_ymargin(0.18)  # room above B's label and below A's and C's
    axes[-1].set_xlabel("time [ms]")
    _mark_points(axes, data.points)
    if data.flies:
        _mark_flights(axes, result)
    fig.suptitle(_trace_title(result))
    return fig


def flies(result: SimulationResult) -> bool:
    """Whether a sampled run leaves the track within its samples (a lift-off, or a sample in flight)."""
    traj = result.trajectory
    assert traj is not None
    return bool(np.any(traj.mode == Mode.FLIGHT)) or any(
        event.kind is EventKind.LIFT_OFF and event.t <= traj.t[-1] for event in result.events)


def _trace_title(result: SimulationResult) -> str:
    """The inputs and the plant; the general model's angles and Gamma where they differ from Kostek's,
    and a resonant plant's exciter (its drive level in place of Pa, which it does not use)."""
    p, i = result.params, result.inputs
    excitation = f"drive level {i.drive_level:g}" if p.resonant else f"$P_a$ = {i.excitation_amplitude:g} N"
    title = (f"{excitation}, $F_d$ = {i.drive_force:g} N, $f$ = {i.excitation_frequency:g} Hz, "
             f"$\\mu$ = {p.mu:g}, $g$ = {p.gravity:g} m/s², $m$ = {p.mass:g} kg")
    extra = []
    if p.resonant:
        extra.append(f"resonant exciter: $f_n$ = {p.natural_frequency:g} Hz, $\\zeta$ = {p.damping_ratio:g}, "
                     f"$A$ = {p.full_drive_acceleration:g} m/s²")
    if p.excitation_angle != 90.0 or p.excitation_phase != 0.0:
        extra.append(f"$\\beta$ = {p.excitation_angle:g}°, $\\psi$ = {p.excitation_phase:g}°")
    if p.track_inclination != 0.0:
        extra.append(f"$\\alpha$ = {p.track_inclination:g}°")
    if p.static_ratio != 1.0:
        extra.append(f"$\\mu_s/\\mu$ = {p.static_ratio:g}")
    if flies(result):
        extra.append(f"$\\Gamma$ = {result.throw_number:.4g}, $e$ = {p.restitution:g}, "
                     f"landing friction {p.landing_friction}")
    return title + ("\n" + ", ".join(extra) if extra else "")


def _mark_flights(axes: np.ndarray, result: SimulationResult) -> None:
    """Mark every lift-off (triangle up) and landing (triangle down) on the
    height panel, with a thin dotted line through every panel."""
    traj = result.trajectory
    assert traj is not None
    height = axes[4]
    shown: set[str] = set()
    for event in result.events:
        if event.t > traj.t[-1] or event.kind not in (EventKind.LIFT_OFF, EventKind.LANDING):
            continue
        lift = event.kind is EventKind.LIFT_OFF
        label = ("lift-off" if lift else "landing")
        height.plot(event.t * 1e3, 0.0, "^" if lift else "v", color="tab:green" if lift else "tab:red",
                    markersize=6, label=None if label in shown else label, clip_on=False, zorder=3)
        shown.add(label)
        for axis in axes:
            axis.axvline(event.t * 1e3, color="tab:green" if lift else "tab:red", linewidth=0.5,
                         linestyle=":", zorder=0)
    if shown:
        height.legend(loc="upper right", fontsize=8)


def _points(result: SimulationResult) -> tuple[tuple[str, float, float], ...]:
    """A (slip starts), B (fastest) and C (stick) within the samples, as (label, t, v),
    in time order: A and C are the slider's events (v = 0 there), B each peak of the
    speed in a slip, on the sampled path (:func:`_fastest`)."""
    traj = result.trajectory
    assert traj is not None
    end = traj.t[-1]
    events = [event for event in result.events if event.t <= end]
    stops = [event.t for event in events if event.kind is EventKind.STICK]
    ends = sorted(stops + [event.t for event in events if event.kind is EventKind.LIFT_OFF])
    points: list[tuple[str, float, float]] = [("C", t, 0.0) for t in stops]
    for event in events:
        if event.kind is EventKind.SLIP_START:
            stop = next((t for t in ends if t > event.t), end)
            points += [("A", event.t, 0.0)] + [("B", t, float(np.interp(t, traj.t, traj.v)))
                                                for t in _fastest(result, event.t, stop)]
    return tuple(sorted(points, key=lambda point: point[1]))


def _mark_points(axes: np.ndarray, points: Sequence[tuple[str, float, float]]) -> None:
    """Mark A, B and C on the velocity axis, with a thin line through every panel."""
    speed_axis = axes[2]
    for label, t, v in points:
        speed_axis.plot(t * 1e3, v * 1e3, "o", color="tab:purple", markersize=5)
        # Labels clear of the curve: A left of the point (the curve leaves it to the right),
        # B on the outside of the peak, C right of the point.
        offset = {"A": (-11, 6), "B": (4, 6 if v >= 0.0 else -15), "C": (4, 6)}[label]
        speed_axis.annotate(label, (t * 1e3, v * 1e3), textcoords="offset points", xytext=offset, fontsize=9)
        for axis in axes:
            axis.axvline(t * 1e3, color="0.75", linewidth=0.6, zorder=0)


def _fastest(result: SimulationResult, t_start: float, end: float) -> list[float]:
    """Where the speed peaks in a slip from ``t_start`` to ``end`` (B: mu R rises back
    through |Ft|): each sign change of the sampled acceleration along the slip from
    + to -, between two samples, placed by linear interpolation (within a small part
    of the sample spacing: the acceleration is smooth within a slip)."""
    traj = result.trajectory
    assert traj is not None
    inside = np.nonzero((traj.t > t_start) & (traj.t < end) & (traj.mode != Mode.STUCK)
                        & (traj.mode != Mode.FLIGHT))[0]
    if inside.size < 2:
        return []
    way = np.sign(traj.v[inside])
    along = way * traj.acceleration[inside]
    found = []
    for k in np.nonzero((along[:-1] > 0.0) & (along[1:] <= 0.0) & (way[:-1] == way[1:]))[0]:
        a0, a1 = along[k], along[k + 1]
        t0, t1 = traj.t[inside[k]], traj.t[inside[k + 1]]
        found.append(float(t0 + (t1 - t0) * a0 / (a0 - a1)))
    return found


def tuning_figure(curve: TuningCurve) -> Figure:
    """The resonant feeder's tuning curve against the drive frequency: the
    slideway's amplitude, its lag behind the drive (90 degrees at f_n) and the
    mean conveying speed, f_n and the fastest frequency marked."""
    fig = pyplot_free_figure(figsize=(7.0, 8.0), layout="constrained")
    top, middle, bottom = fig.subplots(3, 1, sharex=True)
    f, params = curve.frequency, curve.params
    top.plot(f, curve.amplitude, color="tab:blue", linewidth=1.3)
    top.set_ylabel(r"slideway amplitude [m/s$^2$]")
    top.set_title(rf"Tuning curve: $f_n$ = {params.natural_frequency:g} Hz, $\zeta$ = {params.damping_ratio:g}, "
                  rf"drive level {curve.inputs.drive_level:g}")
    middle.plot(f, curve.lag_deg, color="tab:green", linewidth=1.3)
    middle.axhline(90.0, color="0.4", linestyle=":", linewidth=0.9)
    middle.set_ylabel("lag behind the drive [deg]")
    bottom.plot(f, curve.mean_velocity * 1e3, color="black", linewidth=1.3)
    best = curve.fastest
    bottom.plot(f[best], curve.mean_velocity[best] * 1e3, "*", color="tab:red", markersize=11,
                label=f"fastest: {f[best]:.4g} Hz")
    bottom.axhline(0.0, color="black", linewidth=0.6)
    bottom.set_ylabel("mean speed V [mm/s]")
    bottom.set_xlabel("drive frequency f [Hz]")
    bottom.legend(loc="upper left", fontsize=8)
    for axes in (top, middle, bottom):
        axes.axvline(params.natural_frequency, color="tab:red", linestyle="--", linewidth=0.9)
        axes.grid(alpha=0.3)
    return fig


def calibration_figure(calibration: Calibration) -> Figure:
    """Measured against fitted mean speed over the points: against the first
    setting that varies (the points sorted along it; each one's error bar its
    standard deviation when given), and the fitted against the measured."""
    fig = pyplot_free_figure(figsize=(11.0, 4.6), layout="constrained")
    left, right = fig.subplots(1, 2)
    m = calibration.measurements
    numeric = [name for name, values in m.settings.items() if values.dtype.kind == "f"]
    x = m.settings[numeric[0]] if numeric else np.arange(1, m.count + 1, dtype=float)
    order = np.argsort(x, kind="stable")
    errors = m.std[order] * 1e3 if m.std is not None else None
    left.errorbar(x[order], m.speed[order] * 1e3, yerr=errors, fmt="o", color="black", markersize=4,
                  label="measured")
    left.plot(x[order], calibration.fitted_speed[order] * 1e3, "-", color="tab:red", linewidth=1.3, label="fitted")
    left.set_xlabel(numeric[0] if numeric else "point")
    left.set_ylabel("mean speed V [mm/s]")
    left.legend(fontsize=8)
    top = 1e3 * float(max(np.max(m.speed), np.max(calibration.fitted_speed)))
    right.plot(m.speed * 1e3, calibration.fitted_speed * 1e3, "o", color="tab:blue", markersize=4)
    right.plot([0.0, top], [0.0, top], ":", color="0.4", linewidth=0.9)
    right.set_xlabel("measured V [mm/s]")
    right.set_ylabel("fitted V [mm/s]")
    fig.suptitle("Calibration: " + ", ".join(f"{e.name} = {e.value:.6g} ± {e.std_error:.2g}"
                                              for e in calibration.estimates), fontsize=10)
    for axes in (left, right):
        axes.grid(alpha=0.3)
    return fig


def run_calibration_figure(result: RunCalibration) -> Figure:
    """A fit to a recording: the recorded position and velocity (points) and the
    fitted model's (line) against time, and each one's residual below."""
    fig = pyplot_free_figure(figsize=(10.0, 7.0), layout="constrained")
    (x_axes, v_axes), (dx_axes, dv_axes) = fig.subplots(2, 2, sharex=True)
    run = result.run
    tx, tv = run.pose_ns / 1e9, run.velocity_ns / 1e9
    x_axes.plot(tx, run.x * 1e3, ".", color="0.5", markersize=2, label="recorded")
    x_axes.plot(tx, result.fitted_x * 1e3, "-", color="tab:red", linewidth=1.0, label="fitted")
    v_axes.plot(tv, run.v * 1e3, ".", color="0.5", markersize=2, label="recorded")
    v_axes.plot(tv, result.fitted_v * 1e3, "-", color="tab:red", linewidth=1.0, label="fitted")
    dx_axes.plot(tx, (run.x - result.fitted_x) * 1e6, ".", color="tab:blue", markersize=2)
    dv_axes.plot(tv, (run.v - result.fitted_v) * 1e3, ".", color="tab:blue", markersize=2)
    x_axes.set_ylabel("x [mm]")
    v_axes.set_ylabel("v [mm/s]")
    dx_axes.set_ylabel(r"recorded $-$ fitted x [$\mu$m]")
    dv_axes.set_ylabel(r"recorded $-$ fitted v [mm/s]")
    for axes in (dx_axes, dv_axes):
        axes.set_xlabel("time [s]")
    for axes in (x_axes, v_axes, dx_axes, dv_axes):
        axes.grid(alpha=0.3)
    x_axes.legend(fontsize=8)
    fig.suptitle("Calibration against a recording: " + ", ".join(
        f"{e.name} = {e.value:.6g} ± {e.std_error:.2g}" for e in result.estimates), fontsize=10)
    return fig


def reduction_figure(curves: ReductionCurves) -> Figure:
    """The friction-reduction curve: mu_app/mu needed to slide at a mean speed,
    against the speed at several Pa/Q (left) and against Pa/Q at several speeds
    (right); 1 is the full Coulomb friction, below it what the vibration
    removes (the paper's Fig. 4, without Lomakin's points: none are available)."""
    fig = pyplot_free_figure(figsize=(11.0, 4.8), layout="constrained")
    left, right = fig.subplots(1, 2, sharey=True)
    params = curves.params
    for ratio, speeds, row in zip(curves.ratios, curves.speeds, curves.by_speed):
        left.plot(speeds * 1e3, row, linewidth=1.3, label=f"Pa/Q = {ratio:g}")
    for speed, ratios, row in zip(curves.marked_speeds, curves.amplitudes, curves.by_amplitude):
        right.plot(ratios, row, linewidth=1.3, label=f"V = {speed * 1e3:g} mm/s")
    left.set_xlabel("mean speed V [mm/s]")
    right.set_xlabel("amplitude ratio Pa/Q")
    left.set_ylabel(r"apparent friction $\mu_{app}/\mu$")
    model = "Kostek's model, exact" if curves.closed_form else "general model, simulated exactly"
    fig.suptitle(rf"Friction reduction by vibration: $\mu$ = {params.mu:g}, m = {params.mass:g} kg, "
                 rf"g = {params.gravity:g} m/s$^2$, f = {curves.frequency:g} Hz ({model})", fontsize=10)
    for axes in (left, right):
        axes.axhline(1.0, color="0.4", linestyle=":", linewidth=0.9)
        axes.grid(alpha=0.3)
        axes.legend(loc="lower right", fontsize=8)
    return fig


def conveyor_figure(sweep: ConveyorSweep) -> Figure:
    """U against the throw number for each vibration angle (level track, Fd = 0),
    Gamma = 1 and 3.30 marked and each curve's peak starred; below, U against the
    track inclination at a fixed Gamma and angle, the reversal marked.  Hollow
    markers: motion not periodic within the settling periods (the mean is over
    the stated window after them)."""
    from friction_sim.core.meanspeed.conveyor import MARKED_GAMMAS

    fig = pyplot_free_figure(figsize=(8.0, 9.0), layout="constrained")
    top, bottom = fig.subplots(2, 1)
    colours = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")
    for (angle, c), colour in zip(sweep.gamma_curves.items(), colours * 4):
        top.plot(c.x, c.u, color=colour, linewidth=1.3, label=rf"$\beta$ = {angle:g}°")
        _hollow(top, c.x, c.u, c.periodic, colour)
        best = sweep.peaks[angle]
        top.plot(best.throw_number, best.u, "*", color=colour, markersize=11, markeredgecolor="black",
                 markeredgewidth=0.5, zorder=4)
    for gamma, text in MARKED_GAMMAS:
        top.axvline(gamma, color="0.35", linestyle="--", linewidth=0.9, zorder=0)
        top.annotate(text, (gamma, 1.0), xycoords=("data", "axes fraction"), xytext=(0, 3),
                     textcoords="offset points", va="bottom", ha="center", fontsize=8, color="0.25")
    top.plot([], [], "o", markerfacecolor="none", markeredgecolor="0.3", label="not periodic (window mean)")
    top.plot([], [], "*", color="0.5", markeredgecolor="black", markeredgewidth=0.5, markersize=10,
             label="peak speed")
    top.axhline(0.0, color="black", linewidth=0.6)
    top.set_xlim(0.0, max(float(c.x[-1]) for c in sweep.gamma_curves.values()))
    top.set_xlabel(r"throw number $\Gamma = P_a / (m g \cos\alpha)$")
    top.set_ylabel(r"$U = V f / (g \mu)$")
    top.set_title(rf"Level track, $F_d$ = 0, $\mu$ = {sweep.mu:g}", pad=16)
    top.legend(loc="upper left", fontsize=8)
    top.grid(alpha=0.3)

    slope = sweep.slope
    bottom.plot(slope.x, slope.u, color="black", linewidth=1.3)
    _hollow(bottom, slope.x, slope.u, slope.periodic, "black")
    bottom.axhline(0.0, color="black", linewidth=0.6)
    if sweep.reversal is not None:
        bottom.axvline(sweep.reversal, color="tab:red", linestyle="--", linewidth=1.0)
        bottom.plot(sweep.reversal, 0.0, "o", color="tab:red", zorder=4,
                    label=rf"reversal: $\alpha$ = {sweep.reversal:.3f}°")
        bottom.legend(loc="upper right", fontsize=8)
    bottom.set_xlabel(r"track inclination $\alpha$ [°] (> 0: conveying uphill)")
    bottom.set_ylabel(r"$U = V f / (g \mu)$")
    bottom.set_title(rf"$\Gamma$ = {sweep.slope_gamma:g}, $\beta$ = {sweep.slope_angle:g}°, "
                     rf"$F_d$ = 0, $\mu$ = {sweep.mu:g}")
    bottom.grid(alpha=0.3)
    fig.suptitle("Vibratory conveying: mean speed of the exact point-mass model")
    return fig


def _hollow(ax: Any, x: np.ndarray, u: np.ndarray, periodic: np.ndarray, colour: str) -> None:
    """Hollow markers on the points whose motion is not periodic."""
    irregular = ~periodic & np.isfinite(u)
    if np.any(irregular):
        ax.plot(x[irregular], u[irregular], "o", markerfacecolor="none", markeredgecolor=colour, markersize=4,
                linewidth=0.0)


def input_panels(data: RunData) -> list[tuple[str, list[float], list[float]]]:
    """The report picture's input panels as (label, times, values) steps: what the
    plant acts on.  The force actuator: Pa, Fd, f.  The resonant one (whose Pa is
    no input): its drive level u, the slideway's steady normal acceleration
    amplitude u*A*G(f/f_n) [m/s^2] at each, Fd and f."""
    times = [0.0] + [c.t for c in data.commands] + [data.duration]
    states = [data.inputs] + [inputs_at(data, c.t) for c in data.commands]
    params = data.params
    quantities: list[tuple[str, Callable[[Inputs], float]]] = [
        ("Pa [N]", lambda i: i.excitation_amplitude)]
    if params.resonant:
        quantities = [("drive level u", lambda i: i.drive_level),
                      ("slideway [m/s$^2$]", lambda i: slideway_amplitude(params, i)[0])]
    quantities += [("Fd [N]", lambda i: i.drive_force), ("f [Hz]", lambda i: i.excitation_frequency)]
    panels = []
    for label, of in quantities:
        values = [of(state) for state in states]
        panels.append((label, times, values + values[-1:]))
    return panels


def report_figure(data: RunData, rows: Sequence[SegmentRow]) -> Figure:
    """Target and measured mean speed, and the inputs in force (:func:`input_panels`)
    against time, the segments' starts marked."""
    panels = input_panels(data)
    fig = pyplot_free_figure(figsize=(10.0, 9.0 + 1.8 * (len(panels) - 3)), layout="constrained")
    ax_v, *axes = fig.subplots(1 + len(panels), 1, sharex=True)
    _speed_panel(ax_v, data, rows)
    for axis, (label, times, values) in zip(axes, panels):
        axis.step(times, values, where="post")
        axis.set_ylabel(label)
    for r in rows[1:]:
        for axis in (ax_v, *axes):
            axis.axvline(r.start, color="0.8", linewidth=0.7, zorder=0)
    axes[-1].set_xlabel("simulation time [s]")
    fig.suptitle(data.name)
    return fig


def _speed_panel(ax: Any, data: RunData, rows: Sequence[SegmentRow]) -> None:
    """Measured mean speed, with each segment's target (closed loop) or prediction (open loop)."""
    ax.plot([t for t, _ in data.mean_velocity], [v * 1e3 for _, v in data.mean_velocity], ".-",
            markersize=2, linewidth=0.7, label="measured mean speed")
    for r in rows:
        ax.plot([r.start, r.end], [r.target * 1e3] * 2, "k--" if r.mode == "closed loop" else "g:", linewidth=1.2)
    ax.plot([], [], "k--", label="target (closed loop)")
    ax.plot([], [], "g:", label="U-relation prediction (open loop)")
    ax.set_ylabel("mean speed [mm/s]")
    ax.legend(loc="upper left", fontsize=8)
