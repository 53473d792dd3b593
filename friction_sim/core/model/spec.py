"""The one vocabulary of friction_sim: every parameter and input, declared once.

Each :class:`Setting` names a value, its default (the paper's Fig. 2 case),
unit, valid range and meaning.  Everything else derives from these tables:
the validated core types (:mod:`friction_sim.core.model.params`), the ROS
parameter descriptors of both nodes, the CLI flags, the node reference's tables
(doc/reference/nodes.md) and ``config/*.yaml`` files (a test checks those against this module).

* :data:`PLANT`: mass, mu, gravity; what the plant is.
* :data:`INPUTS`: what changes while it runs (drive force, excitation
  amplitude and frequency, an external force).
* :data:`SLIDER_NODE` and :data:`CONTROLLER_NODE`: the parameters of each
  node, in the order they are declared.
"""

from __future__ import annotations

import math
import numbers
import sys
from dataclasses import dataclass, field, replace
from typing import Any

from friction_sim.errors import ParameterError

Value = float | int | bool | str
#: Nanoseconds per second: simulation and ROS time in integer nanoseconds (the one unit conversion).
NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class Setting:
    """One parameter or input: its name, default, unit, range and meaning.

    ``low`` and ``high`` bound a number inclusively (None: unbounded);
    ``rule`` states a cross-field rule in words (checked elsewhere, shown in
    the node reference); ``start_only`` marks a node parameter read at start-up only;
    ``flag`` is the CLI option where it differs from ``--name-with-dashes``;
    ``choices`` lists the values a string setting may take (empty: any).
    """

    name: str
    default: Value
    unit: str
    description: str
    low: float | None = None
    high: float | None = None
    rule: str = ""
    start_only: bool = False
    flag: str | None = None
    choices: tuple[str, ...] = ()
    _low: float = field(init=False, repr=False, compare=False, default=-math.inf)
    _high: float = field(init=False, repr=False, compare=False, default=math.inf)

    def __post_init__(self) -> None:
        # The bounds as floats (+-inf when open), for the fast path of check().
        # Open bounds are the largest finite floats, so the fast path below never lets +-inf through.
        object.__setattr__(self, "_low", -sys.float_info.max if self.low is None else float(self.low))
        object.__setattr__(self, "_high", sys.float_info.max if self.high is None else float(self.high))

    @property
    def kind(self) -> type:
        """The value's type: float, int, bool or str (that of the default)."""
        return type(self.default)

    @property
    def option(self) -> str:
        """The CLI option for this setting."""
        return self.flag or "--" + self.name.replace("_", "-")

    def check(self, value: Any) -> Any:
        """``value`` converted to this setting's type, or a :class:`ParameterError`
        that names the field, quotes the value and states the limit."""
        if type(value) is float and type(self.default) is float and self._low <= value <= self._high:
            return value  # the common case, on the path of every input change (NaN fails the comparison)
        kind = self.kind
        if kind is bool:
            if not isinstance(value, bool):
                raise ParameterError(self.name, value, "must be true or false")
            return value
        if kind is str:
            if not isinstance(value, str):
                raise ParameterError(self.name, value, "must be a string")
            if self.choices and value not in self.choices:
                raise ParameterError(self.name, value, f"must be one of {', '.join(self.choices)}")
            return value
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ParameterError(self.name, value, f"must be {'an integer' if kind is int else 'a finite number'}"
                                                   f"{self._range_words()}")
        if kind is int:
            if not isinstance(value, numbers.Integral):
                raise ParameterError(self.name, value, f"must be an integer{self._range_words()}")
            number: int | float = int(value)
        else:
            number = float(value)
            if not math.isfinite(number):
                raise ParameterError(self.name, number, f"must be finite{self._range_words()}")
        if (self.low is not None and number < self.low) or (self.high is not None and number > self.high):
            raise ParameterError(self.name, number, f"must be{' an integer' if kind is int else ''}"
                                                    f"{self._range_words()}")
        return number

    @property
    def dimensioned(self) -> bool:
        """Whether the setting has a unit to print ('' and '-' are none)."""
        return self.unit not in ("", "-")

    @property
    def unit_suffix(self) -> str:
        """`` N`` after a value, or '' for a setting without a unit."""
        return f" {self.unit}" if self.dimensioned else ""

    def _range_words(self) -> str:
        """The range after "must be": `` in [1e-06, 10]``, an integer's bounds written
        out whole (`` in [1, 10000000]``, not 1e+07)."""
        whole = self.kind is int
        low, high = (None if bound is None else f"{int(bound)}" if whole else f"{bound:g}"
                     for bound in (self.low, self.high))
        unit = self.unit_suffix
        if low is not None and high is not None:
            return f" in [{low}, {high}]{unit}"
        if low is not None:
            return f" >= {low}{unit}"
        if high is not None:
            return f" <= {high}{unit}"
        return ""

    def range_text(self) -> str:
        """The range in words: ``1e-06 … 1e+06`` or ``impulsive | none``, or '' if unbounded
        (plain text: :func:`markdown_table` escapes it for a table)."""
        if self.choices:
            return " | ".join(self.choices)
        if self.low is None and self.high is None:
            return ""
        low = "" if self.low is None else _number(self.low)
        high = "" if self.high is None else _number(self.high)
        return f"{low} … {high}"

    def described(self, description: str, **changes: Any) -> Setting:
        """The same value under another node's description (same range and default)."""
        return replace(self, description=description, **changes)


def _number(value: float) -> str:
    return f"{value:g}"


def table(*settings: Setting) -> dict[str, Setting]:
    """Settings by name, in declaration order."""
    return {setting.name: setting for setting in settings}


# -- the plant -------------------------------------------------------------------

MASS = Setting("mass", 1.0, "kg", "slider mass m", 1e-6, 1e6)
MU = Setting("mu", 0.1, "-", "kinetic Coulomb friction coefficient mu", 1e-6, 10.0)
GRAVITY = Setting("gravity", 10.0, "m/s^2", "gravity g", 1e-6, 1e3)
STATIC_RATIO = Setting(
    "static_ratio", 1.0, "-",
    "static over kinetic friction mu_s/mu (stuck while the tangential force is at most mu_s R)", 1.0, 100.0)
EXCITATION_ANGLE = Setting(
    "excitation_angle", 90.0, "deg", "vibration angle beta to the track; tangential amplitude Pt = Pa cot(beta) "
    "(90: normal only, the paper)", 0.1, 90.0, flag="--angle")
EXCITATION_PHASE = Setting("excitation_phase", 0.0, "deg", "phase psi of the tangential excitation Pt sin(theta + psi) "
                           "(0: linear drive; +-90: elliptical)", -180.0, 180.0, flag="--phase")
TRACK_INCLINATION = Setting("track_inclination", 0.0, "deg", "track slope alpha (> 0: conveying uphill)",
                            -89.0, 89.0, flag="--inclination")
RESTITUTION = Setting("restitution", 0.0, "-", "normal restitution e at landing (0: plastic)", 0.0, 0.99)
LANDING_FRICTION = Setting(
    "landing_friction", "impulsive", "-", "tangential impulse at landing: impulsive (Coulomb impact, bounded by "
    "mu times the normal impulse) or none (tangential velocity kept)", choices=("impulsive", "none"))
ACTUATOR = Setting(
    "actuator", "force", "-", "what vibrates the slideway: force (Pa and f set the excitation directly, the paper) "
    "or resonant (a slideway on springs driven at drive_level and f: the excitation follows with its lag and "
    "transients)", choices=("force", "resonant"), rule="resonant needs excitation_phase 0")
NATURAL_FREQUENCY = Setting("natural_frequency", 50.0, "Hz", "resonant actuator: natural frequency f_n of the "
                            "slideway on its springs", 1e-3, 20_000.0)
DAMPING_RATIO = Setting("damping_ratio", 0.02, "-", "resonant actuator: damping ratio zeta (Q = 1/(2 zeta)); a "
                        "change of drive settles with time constant 1/(2 pi zeta f_n)", 1e-4, 0.7)
FULL_DRIVE_ACCELERATION = Setting(
    "full_drive_acceleration", 10.0, "m/s^2", "resonant actuator: steady normal acceleration amplitude of the "
    "slideway at full drive (drive_level 1) at resonance (f = f_n)", 0.0, 1e4)
PLANT = table(MASS, MU, GRAVITY, STATIC_RATIO, EXCITATION_ANGLE, EXCITATION_PHASE, TRACK_INCLINATION, RESTITUTION,
              LANDING_FRICTION, ACTUATOR, NATURAL_FREQUENCY, DAMPING_RATIO, FULL_DRIVE_ACCELERATION)
#: The settings of the resonant actuator (ignored by the force actuator).
EXCITER = table(NATURAL_FREQUENCY, DAMPING_RATIO, FULL_DRIVE_ACCELERATION)

# -- the inputs ------------------------------------------------------------------

MAX_FORCE = 1e6
DRIVE_FORCE = Setting("drive_force", 0.7, "N", "drive force Fd along +x (negative drives backwards)",
                      -MAX_FORCE, MAX_FORCE)
EXCITATION_AMPLITUDE = Setting(
    "excitation_amplitude", 5.0, "N", "excitation amplitude Pa of the normal force (above m g cos(alpha) the "
    "slider hops; the resonant actuator refuses a command of it: set drive_level)", 0.0, MAX_FORCE, flag="--amplitude")
#: The real-time loop simulates at most this many excitation periods per wall
#: second (f times the real-time factor): each costs the core ~10 us, and a
#: tick must stay well inside its millisecond.
MAX_PERIODS_PER_SECOND = 20_000.0
EXCITATION_FREQUENCY = Setting(
    "excitation_frequency", 50.0, "Hz", "excitation frequency f; the phase stays continuous when it changes",
    1e-3, MAX_PERIODS_PER_SECOND, rule="f x real_time_factor <= 20000 in real time", flag="--frequency")
EXTERNAL_FORCE_X = Setting("external_force_x", 0.0, "N", "extra tangential force Fx, added to Fd",
                           -MAX_FORCE, MAX_FORCE)
EXTERNAL_FORCE_Z = Setting("external_force_z", 0.0, "N", "extra force Fz along +z, away from the track; > 0 lifts",
                           -MAX_FORCE, MAX_FORCE)
DRIVE_LEVEL = Setting("drive_level", 0.5, "-", "resonant actuator: drive level u of the exciter (1: full drive; "
                      "the force actuator refuses a command of it)", 0.0, 1.0)
INPUTS = table(DRIVE_FORCE, EXCITATION_AMPLITUDE, EXCITATION_FREQUENCY, EXTERNAL_FORCE_X, EXTERNAL_FORCE_Z,
               DRIVE_LEVEL)

# -- the real-time loop ------------------------------------------------------------

MAX_MEAN_WINDOW = 10_000
PUBLISH_RATE = Setting("publish_rate", 1000.0, "Hz", "state publishing rate", 1.0, 10_000.0)
REAL_TIME_FACTOR = Setting("real_time_factor", 1.0, "-", "simulated seconds per wall second", 1e-3, 1e3)
MAX_CATCH_UP = Setting("max_catch_up", 0.02, "s", "wall time a late tick simulates at most (at least two ticks): "
                       "the rest of a longer stall of the host is not simulated, so the plant never runs on "
                       "ahead of its controllers; counted in diagnostics (stalls, time_slipped)", 1e-3, 3600.0)
PUBLISH_CLOCK = Setting("publish_clock", False, "-", "publish simulation time on /clock")
MEAN_WINDOW_PERIODS = Setting("mean_window_periods", 1, "periods", "whole periods averaged in mean_velocity",
                              1, MAX_MEAN_WINDOW)
FRAME_ID = Setting("frame_id", "slideway", "-", "header.frame_id of published messages")
LOG_PATH = Setting("log_path", "", "-", "record the run to this MCAP file ('' = no recording)", start_only=True)
LOG_RATE = Setting("log_rate", 1000.0, "Hz", "recorded state samples per simulated second", 1.0, 100_000.0,
                   start_only=True)
FOXGLOVE_PORT = Setting("foxglove_port", 0, "-", "serve a Foxglove live view (WebSocket) on this TCP port "
                        "(0 = off; -1 = a free port the system chooses, the URL is logged; Foxglove's usual "
                        "port is 8765)", -1, 65535, start_only=True)
FOXGLOVE_ADDRESS = Setting("foxglove_address", "127.0.0.1", "-", "address the live view listens on "
                           "(0.0.0.0: every interface)", start_only=True)
DIAGNOSTICS_PERIOD = Setting("diagnostics_period", 1.0, "s", "seconds between diagnostics messages (the "
                             "interval their rates and counts cover): wall-clock seconds, simulated ones in lockstep",
                             0.05, 3600.0, start_only=True)

# -- lockstep (the slider advances when its participants have answered) ---------------------

LOCKSTEP = Setting("lockstep", False, "-", "lockstep: simulation time advances only when every participant "
                   "has answered (as fast as the CPU allows), not with the wall clock", start_only=True)
#: The participants a slider in lockstep may wait for (lockstep_participants).
LOCKSTEP_ROLES = ("controller", "scheduler")
LOCKSTEP_PARTICIPANTS = Setting(
    "lockstep_participants", "controller", "-", "lockstep: who the slider waits for, comma-separated: controller "
    "(an answer on control_answer to each mean_velocity sample), scheduler (a promise on stamped_command of what "
    "comes next); '' = nobody", start_only=True, rule="each of controller, scheduler")
ACTUATION_DELAY = Setting("actuation_delay", 0.0, "s", "lockstep: simulation time from a mean_velocity sample to "
                          "the moment the controller's answer to it acts on the plant", 0.0, 10.0, start_only=True)
LOCKSTEP_TIMEOUT = Setting("lockstep_timeout", 10.0, "s", "lockstep: wall time the slider waits for a participant "
                           "before it names it and the run stops", 0.1, 3600.0, start_only=True)

# -- the accelerometer ------------------------------------------------------------------

ACCELEROMETER_RATE = Setting(
    "accelerometer_rate", 0.0, "Hz", "publish the slideway's acceleration on accelerometer (sensor_msgs/Imu, "
    "track frame, gravity included) at this many samples per simulated second (0 = off)", 0.0, 100_000.0,
    start_only=True)
ACCELEROMETER_NOISE = Setting("accelerometer_noise", 0.0, "m/s^2", "standard deviation of the accelerometer's white "
                              "noise, per axis and sample (seeded by accelerometer_seed)", 0.0, 1e6, start_only=True)
ACCELEROMETER_BIAS = Setting("accelerometer_bias", 0.0, "m/s^2", "constant bias of the accelerometer on every axis",
                             -1e6, 1e6, start_only=True)
ACCELEROMETER_SEED = Setting("accelerometer_seed", 0, "-", "seed of the accelerometer's noise", 0, 2**31 - 1,
                             start_only=True)

# -- simulation control (the ~/step service) -------------------------------------------

STEP_PERIODS = Setting("step_periods", 1, "periods", "excitation periods one ~/step call advances "
                       "(when step_time is 0)", 1, 10_000)
STEP_TIME = Setting("step_time", 0.0, "s", "simulated seconds one ~/step call advances (0: step_periods "
                    "periods instead)", 0.0, 100.0)

# -- mean-speed windows of batch runs (sweeps, calibrations, the general mean speed) -------------

SETTLE_PERIODS = Setting("settle_periods", 200, "periods", "whole excitation periods simulated before the mean "
                         "speed is averaged (the general mean speed: the most the motion may take to repeat)",
                         0, 1_000_000)
PERIODS = Setting("periods", 200, "periods", "whole excitation periods the mean speed is averaged over", 1, 10_000_000)
CHUNK_SIZE = Setting("chunk_size", 5000, "points", "points of a sweep per batch-core call (a Dask task)", 1, 10_000_000)
INITIAL = Setting("initial", "steady", "-", "resonant actuator: how the exciter starts at t = 0: steady (running in "
                  "steady state, as a slider starts on a running feeder) or rest (the slideway at rest: the feeder's "
                  "start-up transient, as after a step of drive level from 0)", choices=("steady", "rest"))
#: The inputs a batch run's resonant exciter may start from the steady state of (a step of
#: drive level or frequency at t = 0: ``initial: rest`` is a drive level of 0).
EXCITER_START = ("drive_level", "excitation_frequency")
#: The inputs each value of :data:`INITIAL` starts the exciter from (none: the slider's own).
INITIAL_INPUTS: dict[str, dict[str, float]] = {"steady": {}, "rest": {"drive_level": 0.0}}

# -- the controller ------------------------------------------------------------------

TARGET_SPEED = Setting("target_speed", 0.0002, "m/s", "target mean speed V*", -1e3, 1e3)
INTEGRAL_GAIN = Setting("integral_gain", 0.4, "-", "first integral step, fraction of the error in U", 0.0, 2.0)
MAX_AMPLITUDE_RATIO = Setting("max_amplitude_ratio", 0.95, "-", "largest Pa/(m g) applied (above 1 the slider "
                              "hops)", 1e-3, 10.0)
SETTLE_MARGIN = Setting(
    "settle_margin", 0.25, "periods",
    "how far a sample window keeps clear of a change of Pa, on top of the delivery jitter seen", 0.0, 5.0)
PLANT_NODE = Setting("plant_node", "slider", "-", "the plant node whose model, window, Fd and f are read at "
                                                  "start-up and followed on /parameter_events ('' = none)")
ACTIVE = Setting("active", True, "-", "regulate now; false: stand by (publish nothing) until a target arrives")
INNER_LOOP = Setting("inner_loop", True, "-", "resonant actuator: regulate the slideway's amplitude from the "
                     "accelerometer, period by period (false: the drive level through the model's steady gain, "
                     "no accelerometer needed)")
TRACK_RESONANCE = Setting("track_resonance", False, "-", "resonant actuator, inner loop: move the drive frequency "
                          "(published on excitation_frequency) to hold the slideway at resonance as its load moves f_n")

# -- the nodes ---------------------------------------------------------------------

SLIDER_NODE = table(
    MASS, MU, GRAVITY, STATIC_RATIO, EXCITATION_ANGLE, EXCITATION_PHASE, TRACK_INCLINATION, RESTITUTION,
    LANDING_FRICTION, ACTUATOR, NATURAL_FREQUENCY, DAMPING_RATIO, FULL_DRIVE_ACCELERATION,
    DRIVE_FORCE.described("drive force Fd along +x; setting it acts like the topic"),
    EXCITATION_AMPLITUDE, EXCITATION_FREQUENCY, DRIVE_LEVEL,
    PUBLISH_RATE, REAL_TIME_FACTOR, MAX_CATCH_UP, PUBLISH_CLOCK, MEAN_WINDOW_PERIODS, FRAME_ID, LOG_PATH,
    LOG_RATE, FOXGLOVE_PORT, FOXGLOVE_ADDRESS, STEP_PERIODS, STEP_TIME, DIAGNOSTICS_PERIOD,
    ACCELEROMETER_RATE, ACCELEROMETER_NOISE, ACCELEROMETER_BIAS, ACCELEROMETER_SEED,
    LOCKSTEP, LOCKSTEP_PARTICIPANTS, ACTUATION_DELAY, LOCKSTEP_TIMEOUT,
)
CONTROLLER_NODE = table(
    MASS.described("model: slider mass m (the plant's parameters are replaced at start-up by plant_node's, if it "
                   "answers within 5 s, and follow its changes)"),
    MU.described("model: kinetic Coulomb friction coefficient"),
    GRAVITY.described("model: gravity g"),
    *(setting.described("model: " + setting.description) for setting in (
        STATIC_RATIO, EXCITATION_ANGLE, EXCITATION_PHASE, TRACK_INCLINATION, RESTITUTION, LANDING_FRICTION)),
    ACTUATOR.described("model: the plant's actuator; resonant: this node publishes drive_level, not "
                       "excitation_amplitude"),
    *(setting.described("model: " + setting.description + " (read from plant_node at start-up, not followed: a "
                        "load change is what the inner loop learns)") for setting in (
        NATURAL_FREQUENCY, DAMPING_RATIO, FULL_DRIVE_ACCELERATION)),
    EXCITATION_FREQUENCY.described("initial excitation frequency f; then it follows the topic and plant_node's "
                                   "parameter", rule=""),
    DRIVE_FORCE.described("initial drive force Fd; then it follows the topic and plant_node's parameter"),
    TARGET_SPEED, INTEGRAL_GAIN, MAX_AMPLITUDE_RATIO, SETTLE_MARGIN,
    MEAN_WINDOW_PERIODS.described("the slider's mean_velocity window (read from plant_node, and followed)"),
    PLANT_NODE, ACTIVE, INNER_LOOP, TRACK_RESONANCE, DIAGNOSTICS_PERIOD,
    *(setting.described(setting.description + " (the plant's: read from plant_node at start-up; this value only "
                        "with plant_node '')") for setting in (
        LOCKSTEP.described("the plant runs in lockstep: answer each mean_velocity sample on control_answer"),
        ACTUATION_DELAY, ACCELEROMETER_RATE.described("the plant's accelerometer rate (lockstep: an answer waits "
                                                      "for its readings up to the sample)"))),
)


def markdown_table(settings: dict[str, Setting]) -> str:
    """The Markdown table of ``settings``: one row each with default, unit, range
    (and cross-field rule) and meaning.  The node reference (doc/reference/nodes.md)
    holds exactly this text; a test checks it, so the documentation cannot drift from
    the code."""
    rows = ["| parameter | default | unit | range / rule | meaning |", "|---|---|---|---|---|"]
    for setting in settings.values():
        limits = "; ".join(part for part in (setting.range_text(), setting.rule) if part).replace("|", "\\|") or "–"
        meaning = (setting.description + ("; start-up only" if setting.start_only else "")).replace("|", "\\|")
        unit = setting.unit if setting.dimensioned else "–"
        rows.append(f"| `{setting.name}` | {_default_text(setting.default)} | {unit} | {limits} "
                    f"| {meaning} |")
    return "\n".join(rows) + "\n"


def _default_text(value: Value) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return f"`{value}`" if value else "''"
    return repr(value)


def defaults(settings: dict[str, Setting]) -> dict[str, Value]:
    """name -> default of every setting in ``settings``."""
    return {name: setting.default for name, setting in settings.items()}


__all__ = [
    "CHUNK_SIZE", "CONTROLLER_NODE", "INPUTS", "MAX_MEAN_WINDOW", "MAX_PERIODS_PER_SECOND", "PERIODS", "PLANT",
    "SETTLE_PERIODS", "SLIDER_NODE",
    "Setting", "Value", "defaults", "markdown_table", "table",
]
