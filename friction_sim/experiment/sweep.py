"""Sweep files for ``friction-sim sweep``: parsing, validation and the points.

A sweep runs the batch core (:func:`friction_sim.core.engine.population.run_batch`) over
many points of the general model.  It is a YAML file::

    name: parts                     # optional; names the output file
    settle_periods: 20              # whole periods simulated before averaging
    periods: 50                     # whole periods averaged
    initial: rest                   # resonant actuator: the exciter starts from rest (default steady)
    chunk_size: 2000                # points per batch-core call (a Dask task)
    seed: 7                         # the random stream of `random:` (default 0)
    plant_params: calibrated.yaml   # optional ROS 2 parameters file (friction-sim calibrate's): the plant
                                    #   settings the sections below do not set
    output: out/sweeps/parts.parquet  # optional (default out/sweeps/<name>.parquet)
    fixed:                          # one value for every point
      drive_force: 0.0
    grid:                           # every combination (the last key varies fastest)
      throw_number: {from: 0.5, to: 4.0, num: 36}   # inclusive; `scale: log` for a log grid
      excitation_angle: [15, 30, 45, 60]
    points:                         # optional list: each entry one combination of its keys
      - {track_inclination: 0}
      - {track_inclination: 5}
    samples: 100                    # random parts per combination (needs `random:`)
    random:
      mu: {distribution: normal, mean: 0.3, std: 0.03}   # truncated to mu's range (and low/high)
      mass: {distribution: lognormal, median: 0.01, sigma: 0.1}
      excitation_phase: {distribution: uniform, low: -10, high: 10}
      landing_friction: {distribution: choice, values: [impulsive, none], weights: [0.8, 0.2]}

Keys are any parameter or input of the general model (``core/spec.py``:
``PLANT`` and ``INPUTS``) and three derived ones: ``throw_number``
(Gamma = Pa/(m g cos alpha)) and ``amplitude_ratio`` (a = Pa/(m g)) set
``excitation_amplitude`` point by point, ``drive_ratio`` (phi = Fd/(mu m g))
sets ``drive_force``.  A key appears once, in one section.  What is not given
takes its default.  ``initial`` (``steady``, the default, or ``rest``:
``core/spec.py``'s ``INITIAL``) is how a resonant point's exciter starts at
t = 0: running in steady state, or at rest, its start-up transient run exactly
by the population engine (the force actuator has no exciter: it changes nothing).

The points are the grid combinations, times the ``points`` entries, times
``samples``: point ``p`` is numbered with the samples fastest, then the
``points`` entries, then the grid.  Random values come from fixed blocks of
:data:`BLOCK` points, each with its own stream spawned from ``seed``, so a
point's values never depend on the chunk size or on which worker draws them.

Everything is checked before any work starts, every point included: an
unknown key, a value outside its setting's range, a derived amplitude above the
limit, a distribution that cannot be sampled is a :class:`SweepError`
``file: line N: reason``, through the scenario parser's machinery.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from friction_sim.core.model import spec as settings
from friction_sim.core.model.dimensionless import amplitude_for, amplitude_for_throw, drive_force_for
from friction_sim.core.model.params import cos_degrees
from friction_sim.core.model.spec import Setting
from friction_sim.errors import FrictionSimError, ParameterError
from friction_sim.experiment.scenario import Entry, compose_mapping
from friction_sim.experiment.scenario import YamlParser as ScenarioParser

#: The model's fields: every one is a column of the results.
FIELDS: dict[str, Setting] = {**settings.PLANT, **settings.INPUTS}
#: Derived keys: name -> (the field they set, their setting).
DERIVED: dict[str, tuple[str, Setting]] = {
    "throw_number": ("excitation_amplitude", Setting(
        "throw_number", 0.5, "-", "throw number Gamma = Pa/(m g cos alpha); sets excitation_amplitude", 0.0, 1e6)),
    "amplitude_ratio": ("excitation_amplitude", Setting(
        "amplitude_ratio", 0.5, "-", "a = Pa/(m g); sets excitation_amplitude", 0.0, 1e6)),
    "drive_ratio": ("drive_force", Setting(
        "drive_ratio", 0.7, "-", "phi = Fd/(mu m g); sets drive_force", -1e6, 1e6)),
}
KEYS = (*FIELDS, *DERIVED)
TOP_KEYS = ("name", "description", "output", "settle_periods", "periods", "initial", "chunk_size", "seed",
            "plant_params", "fixed", "grid", "points", "samples", "random")
DISTRIBUTIONS: dict[str, tuple[str, ...]] = {
    "uniform": ("low", "high"),
    "normal": ("mean", "std", "low", "high"),
    "lognormal": ("median", "sigma", "low", "high"),
    "choice": ("values", "weights"),
}
#: Random values are drawn in blocks of this many points, one stream each.
BLOCK = 4096
MAX_POINTS = 10**9
MAX_GRID_VALUES = 100_000
#: A truncated distribution must keep at least this share of its mass (else the file is refused).
MIN_MASS = 1e-3
DEFAULT_CHUNK = int(settings.CHUNK_SIZE.default)


class SweepError(FrictionSimError):
    """A sweep file that cannot be run, with where and why."""


@dataclass(frozen=True)
class Distribution:
    """One ``random:`` entry (see the module docstring)."""

    kind: str
    args: dict[str, Any]


@dataclass(frozen=True)
class Sweep:
    """A validated sweep.  ``lines`` maps each key to the line that gave it,
    so a refusal found while checking the points still names its line."""

    name: str
    settle_periods: int
    periods: int
    chunk_size: int
    seed: int
    fixed: dict[str, Any]
    grid: dict[str, np.ndarray]
    points: dict[str, np.ndarray]
    samples: int
    random: dict[str, Distribution]
    output: Path
    description: str = ""
    #: How a resonant point's exciter starts (:data:`~friction_sim.core.model.spec.INITIAL`).
    initial: str = str(settings.INITIAL.default)
    source: str = field(default="", repr=False)
    where: str = "<sweep>"
    lines: dict[str, int] = field(default_factory=dict, repr=False)

    @property
    def grid_size(self) -> int:
        """Combinations of the grid (1 without one)."""
        return math.prod(len(v) for v in self.grid.values())

    @property
    def list_size(self) -> int:
        """Entries of ``points`` (1 without it)."""
        return len(next(iter(self.points.values()))) if self.points else 1

    @property
    def size(self) -> int:
        """The number of points."""
        return self.grid_size * self.list_size * self.samples

    @property
    def chunks(self) -> int:
        """The number of chunks (batch-core calls)."""
        return -(-self.size // self.chunk_size)

    def chunk_range(self, index: int) -> tuple[int, int]:
        """Points [start, stop) of chunk ``index``."""
        start = index * self.chunk_size
        return start, min(start + self.chunk_size, self.size)

    @property
    def slider_periods(self) -> int:
        """The work: points times the periods simulated per point."""
        return self.size * (self.settle_periods + self.periods)

    @property
    def design_keys(self) -> tuple[str, ...]:
        """Keys that define a combination (grid and points); ``random`` keys vary part to part."""
        return (*self.grid, *self.points)

    @property
    def identity(self) -> str:
        """A digest of what decides every row: the file text and the chunking."""
        return hashlib.sha256(f"{self.source}\0{self.chunk_size}".encode()).hexdigest()[:16]


def load_sweep(path: Path, *, chunk_size: int | None = None) -> Sweep:
    """Read and validate a sweep file; ``chunk_size`` overrides the file's."""
    try:
        text = Path(path).read_text()
    except OSError as error:
        raise SweepError(f"{path}: cannot read: {error.strerror or error}") from error
    return parse_sweep(text, str(path), chunk_size=chunk_size, base=Path(path).parent)


def parse_sweep(text: str, where: str = "<sweep>", *, chunk_size: int | None = None,
                base: Path = Path(".")) -> Sweep:
    """Validate sweep text completely, every point included (``base``: the
    folder a relative ``plant_params`` path is read from)."""
    root = compose_mapping(text, where, SweepError, "a sweep is a mapping of keys (periods, grid, random, ...)")
    sweep = _SweepParser(where, base).sweep(root, text, chunk_size)
    for start in range(0, sweep.size, 1_000_000):
        check_points(sweep, materialize(sweep, start, min(start + 1_000_000, sweep.size)))
    return sweep


class _SweepParser(ScenarioParser):
    """The scenario parser's node walker, refusing with :class:`SweepError`."""

    def fail(self, node: yaml.Node, message: str) -> SweepError:  # type: ignore[override]
        """The one-line refusal ``file: line N: message``."""
        return SweepError(f"{self.where}: line {node.start_mark.line + 1}: {message}")

    def integer(self, entry: Entry, key: str, low: int, high: int) -> int:
        """An integer in [low, high]."""
        node, value = entry
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise self.fail(node, f"{key} = {value!r} rejected: must be an integer in [{low}, {high}]")
        return value

    def sweep(self, root: yaml.MappingNode, text: str, chunk_size: int | None) -> Sweep:
        """The whole sweep, section by section."""
        top = self.mapping(root, TOP_KEYS, "the sweep")
        for key in ("periods",):
            if key not in top:
                raise self.fail(root, f"missing key '{key}' (whole periods averaged per point)")
        self.lines: dict[str, int] = {}
        name = str(top["name"][1]) if "name" in top else "sweep"
        self.exclusive(top)
        fixed = {key: self.value(entry, key) for key, entry in self.section(top, "fixed").items()}
        grid = {key: self.grid_values(entry, key) for key, entry in self.section(top, "grid").items()}
        points = self.point_list(top.get("points"))
        random = {key: self.distribution(entry, key) for key, entry in self.section(top, "random").items()}
        if "plant_params" in top:  # a parameters file (a calibrated plant): what the sections do not set
            given = {*fixed, *grid, *points, *random}
            fixed = {**{key: value for key, value in self.params_file(top["plant_params"]).items()
                        if key in settings.PLANT and key not in given}, **fixed}
        self.unused_inputs(fixed, grid, points, random)
        if random and "samples" not in top:
            raise self.fail(top["random"][0], "random values need 'samples' (parts per combination)")
        samples = self.integer(top["samples"], "samples", 1, MAX_POINTS) if "samples" in top else 1
        size = math.prod(len(v) for v in grid.values()) * (len(next(iter(points.values()))) if points else 1) \
            * samples
        if size > MAX_POINTS:
            raise self.fail(root, f"{size} points: at most {MAX_POINTS} per sweep")
        if chunk_size is not None:  # the caller's (the command line's --chunk-size): checked here, once
            try:
                chunk = int(settings.CHUNK_SIZE.check(chunk_size))
            except ParameterError as error:
                raise SweepError(str(error)) from None
        else:
            chunk = self.checked(top["chunk_size"], settings.CHUNK_SIZE) if "chunk_size" in top else DEFAULT_CHUNK
        return Sweep(
            name=name,
            settle_periods=self.checked(top["settle_periods"], settings.SETTLE_PERIODS)
            if "settle_periods" in top else 0,
            periods=self.checked(top["periods"], settings.PERIODS), chunk_size=chunk,
            initial=self.checked(top["initial"], settings.INITIAL) if "initial" in top
            else str(settings.INITIAL.default),
            seed=self.integer(top["seed"], "seed", 0, 2**63 - 1) if "seed" in top else 0,
            fixed=fixed, grid=grid, points=points, samples=samples, random=random,
            output=Path(str(top["output"][1])) if "output" in top else Path("out") / "sweeps" / f"{name}.parquet",
            description=str(top["description"][1]) if "description" in top else "", source=text,
            where=self.where, lines=self.lines,
        )

    def unused_inputs(self, fixed: dict[str, Any], grid: dict[str, Any], points: dict[str, Any],
                      random: dict[str, Any]) -> None:
        """Refuse a sweep that varies or sets the input none of its actuators
        uses: with only the resonant actuator, the excitation amplitude (and the
        throw number or amplitude ratio that set it); with only the force
        actuator, the drive level.  Every point would run the same plant."""
        given = {**random, **fixed, **grid, **points}
        actuators = {str(v) for v in np.atleast_1d(given.get("actuator", settings.ACTUATOR.default))}
        unused = ({"excitation_amplitude", "throw_number", "amplitude_ratio"} if actuators == {"resonant"} else
                  {"drive_level"} if actuators == {"force"} else set())
        for key in sorted(unused & set(given)):
            line = self.lines.get(key)
            other = "drive_level" if key != "drive_level" else "excitation_amplitude (or throw_number)"
            where = f"line {line}: " if line else ""
            raise SweepError(f"{self.where}: {where}{key} is not used by actuator {actuators.pop()}: "
                             f"set {other} instead")

    def section(self, top: dict[str, Entry], name: str) -> dict[str, Entry]:
        """A section of model keys (fixed, grid, random), remembering each key's line."""
        if name not in top or top[name][1] is None:
            return {}
        entries = self.mapping(top[name][0], KEYS, name)
        for key, (node, _) in entries.items():
            self.lines.setdefault(key, node.start_mark.line + 1)
        return entries

    def exclusive(self, top: dict[str, Entry]) -> None:
        """A key in one section only, and no two keys that set the same field."""
        seen: dict[str, str] = {}
        for name in ("fixed", "grid", "points", "random"):
            if name not in top or top[name][1] is None:
                continue
            node = top[name][0]
            if name == "points":
                first = node.value[0] if isinstance(node, yaml.SequenceNode) and node.value else None
                pairs = first.value if isinstance(first, yaml.MappingNode) else []
            else:
                pairs = node.value if isinstance(node, yaml.MappingNode) else []
            for key_node, _ in pairs:
                key = key_node.value
                target = DERIVED[key][0] if key in DERIVED else key
                if target in seen:
                    raise self.fail(key_node, f"'{key}' in {name} sets {target}, which '{seen[target]}' "
                                              f"already sets: give one of them")
                seen[target] = key

    def setting(self, key: str) -> Setting:
        """The setting that checks ``key``'s values."""
        return setting_of(key)

    def value(self, entry: Entry, key: str) -> Any:
        """One value of ``key``, checked by its setting."""
        node, value = entry
        setting = self.setting(key)
        if setting.kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        try:
            return setting.check(value)
        except ParameterError as error:
            raise self.fail(node, str(error)) from error

    def grid_values(self, entry: Entry, key: str) -> np.ndarray:
        """A grid axis: a list of values or ``{from, to, num[, scale: log]}``."""
        node = entry[0]
        if isinstance(node, yaml.SequenceNode):
            if not node.value:
                raise self.fail(node, f"grid {key}: an empty list")
            values = [self.value((item, yaml.safe_load(yaml.serialize(item))), key) for item in node.value]
            if len(values) > MAX_GRID_VALUES:
                raise self.fail(node, f"grid {key}: at most {MAX_GRID_VALUES} values")
            return np.array(values, dtype=object if self.setting(key).kind is str else float)
        if self.setting(key).kind is str:
            raise self.fail(node, f"grid {key}: give a list of {', '.join(self.setting(key).choices)}")
        fields = self.mapping(node, ("from", "to", "num", "scale"), f"grid {key}")
        for need in ("from", "to", "num"):
            if need not in fields:
                raise self.fail(node, f"grid {key}: give a list, or from, to and num")
        low, high = (self.value(fields[k], key) for k in ("from", "to"))
        num = self.integer(fields["num"], f"grid {key}: num", 1, MAX_GRID_VALUES)
        scale = str(fields["scale"][1]) if "scale" in fields else "linear"
        if scale == "log":
            if low <= 0 or high <= 0:
                raise self.fail(node, f"grid {key}: a log scale needs from and to > 0")
            return np.geomspace(low, high, num)
        if scale != "linear":
            raise self.fail(fields["scale"][0], f"grid {key}: scale = {scale!r} rejected: must be linear or log")
        return np.linspace(low, high, num)

    def point_list(self, entry: Entry | None) -> dict[str, np.ndarray]:
        """``points``: a list of mappings, all with the same keys."""
        if entry is None:
            return {}
        node = entry[0]
        if not isinstance(node, yaml.SequenceNode) or not node.value:
            raise self.fail(node, "points must be a non-empty list of mappings ({mu: 0.1, mass: 1.0})")
        rows = [self.mapping(item, KEYS, "a points entry") for item in node.value]
        keys = list(rows[0])
        for item, row in zip(node.value, rows):
            if list(row) != keys:
                raise self.fail(item, f"every points entry gives the same keys ({', '.join(keys)})")
        for key in keys:
            self.lines.setdefault(key, node.value[0].start_mark.line + 1)
        return {key: np.array([self.value(row[key], key) for row in rows],
                              dtype=object if self.setting(key).kind is str else float) for key in keys}

    def distribution(self, entry: Entry, key: str) -> Distribution:
        """One ``random:`` entry, with its parameters checked and its mass in range."""
        node = entry[0]
        fields = self.mapping(node, ("distribution", *sorted({a for d in DISTRIBUTIONS.values() for a in d})),
                              f"random {key}")
        kind = str(fields["distribution"][1]) if "distribution" in fields else ""
        if kind not in DISTRIBUTIONS:
            raise self.fail(node, f"random {key}: distribution = {kind!r} rejected: must be one of "
                                  f"{', '.join(DISTRIBUTIONS)}")
        extra = [k for k in fields if k not in (*DISTRIBUTIONS[kind], "distribution")]
        if extra:
            raise self.fail(fields[extra[0]][0], f"random {key}: '{extra[0]}' is not a parameter of {kind} "
                                                 f"(allowed: {', '.join(DISTRIBUTIONS[kind])})")
        setting = self.setting(key)
        if kind == "choice":
            return self.choice(fields, node, key)
        if setting.kind is str:
            raise self.fail(node, f"random {key}: a text setting takes distribution: choice")
        required = {"uniform": ("low", "high"), "normal": ("mean", "std"), "lognormal": ("median", "sigma")}[kind]
        for need in required:
            if need not in fields:
                raise self.fail(node, f"random {key}: {kind} needs {' and '.join(required)}")
        args = {k: self.number(fields[k], f"random {key}: {k}") for k in fields if k != "distribution"}
        low = self.value(fields["low"], key) if "low" in fields else _bound(setting.low, -math.inf)
        high = self.value(fields["high"], key) if "high" in fields else _bound(setting.high, math.inf)
        if low >= high:
            raise self.fail(node, f"random {key}: low = {low!r} must be below high = {high!r}")
        args["low"], args["high"] = low, high
        for spread in ("std", "sigma"):
            if spread in args and args[spread] <= 0:
                raise self.fail(fields[spread][0], f"random {key}: {spread} = {args[spread]!r} rejected: must be > 0")
        if kind == "lognormal" and args["median"] <= 0:
            raise self.fail(fields["median"][0], f"random {key}: median = {args['median']!r} rejected: must be > 0")
        mass = _mass_inside(kind, args)
        if mass < MIN_MASS:
            raise self.fail(node, f"random {key}: only {mass:.2g} of the {kind} distribution lies in "
                                  f"[{low:g}, {high:g}] ({key}'s range{' and low/high' if 'low' in fields else ''})")
        return Distribution(kind, args)

    def choice(self, fields: dict[str, Entry], node: yaml.Node, key: str) -> Distribution:
        """``distribution: choice`` with ``values`` and optional ``weights``."""
        if "values" not in fields or not isinstance(fields["values"][0], yaml.SequenceNode) \
                or not fields["values"][0].value:
            raise self.fail(node, f"random {key}: choice needs a non-empty list 'values'")
        values = [self.value((item, yaml.safe_load(yaml.serialize(item))), key) for item in fields["values"][0].value]
        weights = np.full(len(values), 1.0 / len(values))
        if "weights" in fields:
            wnode = fields["weights"][0]
            if not isinstance(wnode, yaml.SequenceNode) or len(wnode.value) != len(values):
                raise self.fail(wnode, f"random {key}: weights must be a list as long as values ({len(values)})")
            raw = [self.number((item, yaml.safe_load(yaml.serialize(item))), f"random {key}: weight")
                   for item in wnode.value]
            if min(raw) < 0 or sum(raw) <= 0:
                raise self.fail(wnode, f"random {key}: weights must be >= 0 with a positive sum")
            weights = np.array(raw) / sum(raw)
        return Distribution("choice", {"values": values, "weights": weights})


def _bound(limit: float | None, open_end: float) -> float:
    """A setting's bound as a float (``open_end`` when unbounded)."""
    return open_end if limit is None else float(limit)


def _normal_cdf(x: float) -> float:
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0))) if math.isfinite(x) else (1.0 if x > 0 else 0.0)


def _mass_inside(kind: str, args: dict[str, Any]) -> float:
    """The share of a distribution inside [low, high]."""
    low, high = args["low"], args["high"]
    if kind == "uniform":
        return 1.0
    if kind == "normal":
        return _normal_cdf((high - args["mean"]) / args["std"]) - _normal_cdf((low - args["mean"]) / args["std"])
    log = (lambda v: math.log(v) if v > 0 else -math.inf)  # noqa: E731 - a one-line map of the bounds
    centre = math.log(args["median"])
    return _normal_cdf((log(high) - centre) / args["sigma"]) - _normal_cdf((log(low) - centre) / args["sigma"])


def _draw(rng: np.random.Generator, dist: Distribution, n: int) -> np.ndarray:
    """``n`` values of ``dist`` (truncated ones redrawn until inside [low, high])."""
    args = dist.args
    if dist.kind == "choice":
        values = np.array(args["values"], dtype=object if isinstance(args["values"][0], str) else float)
        return values[rng.choice(len(values), size=n, p=args["weights"])]
    if dist.kind == "uniform":
        return rng.uniform(args["low"], args["high"], n)
    out = np.empty(n)
    todo = np.arange(n)
    while todo.size:
        if dist.kind == "normal":
            values = rng.normal(args["mean"], args["std"], todo.size)
        else:
            # libm's exp, as the core's: numpy's own (SIMD) exp rounds differently with AVX-512
            # and between numpy versions, and the same sweep would sample other points there.
            logs = rng.normal(math.log(args["median"]), args["sigma"], todo.size).tolist()
            values = np.array([math.exp(v) for v in logs])
        out[todo] = values
        todo = todo[(values < args["low"]) | (values > args["high"])]
    return out


def _random_block(sweep: Sweep, block: int) -> dict[str, np.ndarray]:
    """The random values of points [block*BLOCK, (block+1)*BLOCK), from the block's own stream."""
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(sweep.seed, spawn_key=(block,))))
    return {key: _draw(rng, dist, BLOCK) for key, dist in sweep.random.items()}


def _random_values(sweep: Sweep, start: int, stop: int) -> Iterator[tuple[str, np.ndarray]]:
    """The random columns of points [start, stop)."""
    blocks = [_random_block(sweep, b) for b in range(start // BLOCK, (stop - 1) // BLOCK + 1)]
    offset = start - (start // BLOCK) * BLOCK
    for key in sweep.random:
        yield key, np.concatenate([b[key] for b in blocks])[offset:offset + stop - start]


def materialize(sweep: Sweep, start: int, stop: int) -> dict[str, np.ndarray]:
    """Every column of points [start, stop): ``point``, every model field
    (defaults where not given), each derived key given, in that order."""
    index = np.arange(start, stop, dtype=np.int64)
    n = index.size
    design = index // sweep.samples
    cell, row = np.divmod(design, sweep.list_size)
    given: dict[str, np.ndarray] = {}
    for key, value in sweep.fixed.items():
        given[key] = np.full(n, value, dtype=object if isinstance(value, str) else float)
    if sweep.grid:
        positions = np.unravel_index(cell, tuple(len(v) for v in sweep.grid.values()))
        for (key, values), position in zip(sweep.grid.items(), positions):
            given[key] = values[position]
    for key, values in sweep.points.items():
        given[key] = values[row]
    if sweep.random and n:
        given.update(_random_values(sweep, start, stop))
    columns: dict[str, np.ndarray] = {"point": index}
    for name, setting in FIELDS.items():
        default = setting.default
        columns[name] = given[name] if name in given else np.full(
            n, default, dtype=object if isinstance(default, str) else float)
    derive_fields(columns, given)
    columns.update({key: given[key].astype(float) for key in DERIVED if key in given})
    return columns


def _cos_degrees(angles: np.ndarray) -> np.ndarray:
    """:func:`~friction_sim.core.model.params.cos_degrees` of each angle (the plant's
    own cos(alpha), bit for bit), taken once per distinct angle."""
    distinct, where = np.unique(angles, return_inverse=True)
    return np.array([cos_degrees(float(angle)) for angle in distinct])[where.reshape(angles.shape)]


def setting_of(key: str) -> Setting:
    """The setting that checks the values of ``key`` (a model field or a derived key;
    KeyError for another name)."""
    return DERIVED[key][1] if key in DERIVED else FIELDS[key]


def derive_fields(columns: dict[str, np.ndarray], given: dict[str, np.ndarray]) -> None:
    """Fields set by derived keys: excitation_amplitude and drive_force (from the
    mass, g, mu and slope in ``columns``; sweeps and calibration share it)."""
    weight = columns["mass"].astype(float) * columns["gravity"].astype(float)
    if "throw_number" in given:  # Gamma m g cos(alpha), as SliderParams.normal_weight is m g cos(alpha)
        columns["excitation_amplitude"] = amplitude_for_throw(
            given["throw_number"], weight * _cos_degrees(columns["track_inclination"].astype(float)))
    if "amplitude_ratio" in given:
        columns["excitation_amplitude"] = amplitude_for(given["amplitude_ratio"], weight)
    if "drive_ratio" in given:
        columns["drive_force"] = drive_force_for(given["drive_ratio"], columns["mu"].astype(float), weight)


def check_points(sweep: Sweep, columns: dict[str, np.ndarray]) -> None:
    """Every field of every point in its setting's range, or a :class:`SweepError`
    naming the line of the key that produced the first bad value."""
    for name, setting in FIELDS.items():
        values = columns[name]
        if setting.kind is str:
            bad = ~np.isin(values, setting.choices) if setting.choices else np.zeros(values.size, bool)
        else:
            values = values.astype(float)
            bad = ~((values >= _bound(setting.low, -math.inf)) & (values <= _bound(setting.high, math.inf)))
        if bad.any():
            first = int(np.argmax(bad))
            value = values[first]
            try:
                setting.check(value if isinstance(value, str) else float(value))
                reason = "out of range"
            except ParameterError as error:
                reason = str(error)
            culprit = next((key for key, (target, _) in DERIVED.items()
                            if target == name and key in sweep.lines), name)
            line = sweep.lines.get(culprit)
            where = f"{sweep.where}: line {line}: " if line else f"{sweep.where}: "
            via = f" (from {culprit} = {float(columns[culprit][first])!r})" if culprit != name else ""
            raise SweepError(f"{where}{reason}{via} at point {int(columns['point'][first])}")


__all__ = [
    "BLOCK", "DERIVED", "FIELDS", "KEYS", "Distribution", "Sweep", "SweepError", "check_points", "derive_fields",
    "load_sweep", "setting_of",
    "materialize", "parse_sweep",
]
