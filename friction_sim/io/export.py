"""Writing results to CSV files: the offline jobs' U maps and trajectories, and
a recording's topics (``friction-sim replay --csv``, streamed: one pass over
the file, a row written per message, whatever the length)."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Any

from friction_sim.core.meanspeed.conveyor import ConveyorSweep, Curve
from friction_sim.core.meanspeed.reduction import ReductionCurves
from friction_sim.core.meanspeed.tuning import TuningCurve
from friction_sim.core.meanspeed.urelation import UMap
from friction_sim.core.model.events import Event, Trajectory
from friction_sim.core.model.spec import NS_PER_S
from friction_sim.errors import RecordingError

if TYPE_CHECKING:  # the offline jobs write CSV without loading the ROS message packages
    from friction_sim.io.reader import Recording

TRAJECTORY_COLUMNS = (
    "t", "kind", "x", "v", "acceleration", "friction_force", "normal_force", "phase", "mode", "z", "vz",
)


def write_umap_csv(umap: UMap, path: Path) -> Path:
    """One row per grid point: phi, amplitude_ratio, U (full precision)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(("phi", "amplitude_ratio", "U"))
        for i, ratio in enumerate(umap.amplitude_ratio):
            for j, phi in enumerate(umap.phi):
                writer.writerow((repr(float(phi)), repr(float(ratio)), repr(float(umap.u[i, j]))))
    return path


#: The tuning curve's columns (``friction-sim resonance``).
TUNING_COLUMNS = ("drive_frequency", "amplitude", "lag_deg", "mean_velocity", "flight_fraction")


def write_tuning_csv(curve: TuningCurve, path: Path) -> Path:
    """One row per drive frequency [Hz]: the slideway's normal acceleration
    amplitude [m/s^2], its lag behind the drive [deg], the mean speed [m/s]
    and the flight fraction (full precision)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(TUNING_COLUMNS)
        for row in zip(curve.frequency, curve.amplitude, curve.lag_deg, curve.mean_velocity, curve.flight_fraction):
            writer.writerow([repr(float(value)) for value in row])
    return path


#: The friction-reduction CSV's columns (``friction-sim reduction``).
REDUCTION_COLUMNS = ("view", "amplitude_ratio", "mean_speed", "apparent_friction_ratio", "apparent_friction")


def write_reduction_csv(curves: ReductionCurves, path: Path) -> Path:
    """One row per point of either view: ``view`` is ``speed`` (mu_app/mu against
    the mean speed at a fixed amplitude ratio Pa/Q) or ``amplitude`` (against
    Pa/Q at a fixed speed); mean speed in m/s; the apparent friction coefficient
    itself, mu_app = mu times the ratio; empty where no stick-slip is that fast."""
    path.parent.mkdir(parents=True, exist_ok=True)
    mu = curves.params.mu
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(REDUCTION_COLUMNS)
        for i, ratio in enumerate(curves.ratios):
            for j, speed in enumerate(curves.speeds[i]):
                writer.writerow(_reduction_row("speed", ratio, speed, curves.by_speed[i, j], mu))
        for i, speed in enumerate(curves.marked_speeds):
            for j, ratio in enumerate(curves.amplitudes[i]):
                writer.writerow(_reduction_row("amplitude", ratio, speed, curves.by_amplitude[i, j], mu))
    return path


def _reduction_row(view: str, ratio: float, speed: float, phi: float, mu: float) -> tuple[str, ...]:
    return (view, repr(float(ratio)), repr(float(speed)), *((repr(float(phi)), repr(float(phi * mu)))
                                                           if math.isfinite(phi) else ("", "")))


#: The conveyor CSV's columns: one row per point of either panel.
CONVEYOR_COLUMNS = ("panel", "excitation_angle", "throw_number", "track_inclination", "U", "periodic",
                    "period_multiple", "flight_fraction", "stick_fraction")


def write_conveyor_csv(sweep: ConveyorSweep, path: Path) -> Path:
    """One CSV for both panels of the conveyor figure: ``panel`` is ``gamma`` (U
    against Gamma, level track) or ``inclination`` (U against alpha at the fixed
    Gamma and beta); angles in degrees; ``periodic`` 1/0 (0: the mean over a window)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(CONVEYOR_COLUMNS)
        for angle, c in sweep.gamma_curves.items():
            for k in range(c.x.size):
                writer.writerow(_conveyor_row("gamma", angle, float(c.x[k]), 0.0, c, k))
        for k in range(sweep.slope.x.size):
            writer.writerow(_conveyor_row("inclination", sweep.slope_angle, sweep.slope_gamma,
                                          float(sweep.slope.x[k]), sweep.slope, k))
    return path


def _conveyor_row(panel: str, angle: float, gamma: float, inclination: float, c: Curve, k: int) -> list[object]:
    speeds = c.speeds
    return [panel, repr(angle), repr(gamma), repr(inclination), repr(float(speeds.u[k])), int(speeds.periodic[k]),
            int(speeds.period_multiple[k]), repr(float(speeds.flight_fraction[k])),
            repr(float(speeds.stick_fraction[k]))]


def write_trajectory_csv(trajectory: Trajectory, events: list[Event], path: Path) -> Path:
    """The uniform samples (kind ``sample``) and the events (kind = the event's
    kind, the velocities just after it: v = 0 at slip_start, stick and
    reversal; z = 0 at every event, vz the rebound at a landing), merged in
    time order.  z is the height above the track, vz its rate (0 in contact)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    rows: list[tuple[float, int, tuple[str, ...]]] = []
    for k in range(trajectory.t.size):
        rows.append((float(trajectory.t[k]), 1, (
            repr(float(trajectory.t[k])), "sample", repr(float(trajectory.x[k])),
            repr(float(trajectory.v[k])), repr(float(trajectory.acceleration[k])),
            repr(float(trajectory.friction_force[k])), repr(float(trajectory.normal_force[k])),
            repr(float(trajectory.phase[k])), str(int(trajectory.mode[k])),
            repr(float(trajectory.z[k])), repr(float(trajectory.vz[k])),
        )))
    for event in events:
        rows.append((event.t, 0, (
            repr(event.t), event.kind.value, repr(event.x), repr(float(event.v_after)), "", "", "",
            repr(event.phase), str(int(event.after)), "0.0", repr(float(event.vz_after)),
        )))
    rows.sort(key=lambda row: (row[0], row[1]))
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(TRAJECTORY_COLUMNS)
        writer.writerows(row[2] for row in rows)
    return path


# -- recordings: one CSV per topic ----------------------------------------------------


def flatten(msg: Any, prefix: str = "") -> dict[str, Any]:
    """A message as {dotted.field: value}: nested messages flattened, byte
    fields as integers, sequences as a JSON list (of flattened messages)."""
    from friction_sim.io.cdr import field_names, is_message

    row: dict[str, Any] = {}
    for name in field_names(msg):
        value = getattr(msg, name)
        key = f"{prefix}{name}"
        if is_message(value):
            row.update(flatten(value, key + "."))
        else:
            row[key] = _cell(value)
    return row


def _cell(value: Any) -> Any:
    """One CSV cell: floats at full precision, sequences as JSON."""
    from friction_sim.io.cdr import is_message

    if isinstance(value, bytes):
        return value[0] if len(value) == 1 else value.hex()
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)) or (hasattr(value, "__len__") and hasattr(value, "tolist")
                                            and not isinstance(value, str)):
        items = value.tolist() if hasattr(value, "tolist") else list(value)
        return json.dumps([flatten(v) if is_message(v) else _json_item(v) for v in items])
    return value


def _json_item(value: Any) -> Any:
    """One element of a sequence as JSON takes it (non-finite floats as text)."""
    if isinstance(value, bytes):
        return value[0] if len(value) == 1 else value.hex()
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    return value


def select_topics(recording: Recording, topics: Sequence[str] | None) -> list[str]:
    """The stored names of ``topics`` (as stored, absolute or relative to the
    recorded node) or, if none are given, of every recorded topic;
    RecordingError naming a topic the recording does not have."""
    available = list(recording.topics)
    if not topics:
        return available
    found = {topic: recording.topic_name(topic) for topic in topics}
    unknown = [topic for topic, stored in found.items() if stored is None]
    if unknown:
        raise RecordingError(f"no topic {', '.join(unknown)} in {recording.path}; topics: {', '.join(available)}")
    return list(dict.fromkeys(stored for stored in found.values() if stored is not None))


def export_csv(recording: Recording, directory: str | Path, topics: Sequence[str] | None = None) -> list[Path]:
    """One CSV per topic in ``directory`` (named after the topic relative to
    the recorded node: ``pose.csv``): columns log_time_ns, t (s), then the
    flattened message fields (every message of a topic has its type's)."""
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise RecordingError(f"cannot create {directory}: {error.strerror or error}") from None
    stored = select_topics(recording, topics)
    paths = {topic: directory / (recording.relative_name(topic).strip("/").replace("/", "__") + ".csv")
             for topic in stored}
    try:
        with ExitStack() as files:
            writers = {topic: _TopicCsv(files.enter_context(path.open("w", newline=""))) for topic, path in
                       paths.items()}
            for raw in recording.iter_messages(stored):
                writers[raw.topic].write(raw.log_time, flatten(recording.decode(raw)))
            for writer in writers.values():
                writer.finish()
    except OSError as error:
        raise RecordingError(f"cannot write CSV files in {directory}: {error.strerror or error}") from None
    return list(paths.values())


class _TopicCsv:
    """The CSV of one topic: the header from its first message (or no fields)."""

    def __init__(self, stream: Any) -> None:
        self.writer = csv.writer(stream)
        self.columns: list[str] | None = None

    def write(self, log_time: int, row: dict[str, Any]) -> None:
        """One message's row."""
        if self.columns is None:
            self.columns = list(row)
            self.writer.writerow(["log_time_ns", "t", *self.columns])
        self.writer.writerow([log_time, repr(log_time / NS_PER_S), *(row.get(c, "") for c in self.columns)])

    def finish(self) -> None:
        """The header of a topic without messages."""
        if self.columns is None:
            self.writer.writerow(["log_time_ns", "t"])
