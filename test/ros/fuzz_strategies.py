"""Hypothesis strategies for the fuzz suite (test/ros/test_fuzz.py), derived
from the one vocabulary: every setting of :mod:`friction_sim.core.model.spec` with
its range, and every command topic of :data:`friction_sim.core.model.commands.COMMANDS`
with the fields of its message.

Numbers are drawn from classes rather than uniformly, so that a few hundred
examples reach every edge: values inside the range (near the default and
spread over the whole range), the edges and their neighbours, values just
outside, absurd finite values (1e308, 5e-324, ...), nan and inf, and, for
parameters, values of the wrong type.

An example is a list of :class:`Topic`, :class:`Params`, :class:`Wait` and
:class:`Burst` steps; their reprs are valid Python, so a falsifying example
hypothesis prints can be pasted into ``@example``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from hypothesis import strategies as st

from friction_sim.core.model import spec
from friction_sim.core.model.commands import COMMANDS, consumed_by

NAN, INF = math.nan, math.inf
#: Finite but absurd: the largest and smallest doubles, subnormals, signed zeros.
ABSURD = (1e308, -1e308, 1.7976931348623157e308, -1.7976931348623157e308, 1e-300, -1e-300,
          5e-324, -5e-324, 2.2250738585072014e-308, 0.0, -0.0)
NON_FINITE = (NAN, INF, -INF)
INT64 = (-(2**63), 2**63 - 1)
#: Parameter names no node declares (typos a user makes).
UNKNOWN_NAMES = ("no_such_parameter", "Mass", "drive_force ", "excitation.frequency")
#: rclpy's own parameter, present on every node.
USE_SIM_TIME = "use_sim_time"


# -- steps ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Topic:
    """One message on command topic ``topic`` (or ``mean_velocity`` for the controller):
    ``values`` by message path (``data``, ``wrench.force.x``, ``header.stamp.sec``, ...)."""

    topic: str
    values: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Params:
    """Parameters set through the parameter services: ``kind`` ``set`` (one
    SetParameters request, each parameter on its own, as ``ros2 param set`` and
    ``ros2 param load`` do) or ``atomic`` (one SetParametersAtomically request)."""

    kind: str
    items: tuple[tuple[str, Any], ...]


@dataclass(frozen=True)
class Wait:
    """Let the node run for ``seconds`` (state that diverges over time shows)."""

    seconds: float


@dataclass(frozen=True)
class Burst:
    """``messages`` published back to back, ``repeat`` times (a flood)."""

    messages: tuple[Topic, ...]
    repeat: int = 1


Step = Topic | Params | Wait | Burst


# -- numbers ------------------------------------------------------------------------------


def _finite(low: float, high: float) -> st.SearchStrategy[float]:
    return st.floats(low, high, allow_nan=False, allow_infinity=False)


def _log_spread(low: float, high: float) -> st.SearchStrategy[float]:
    """Magnitudes spread evenly over the decades of [low, high] (either sign where allowed)."""
    top = max(abs(low), abs(high))
    smallest = max(min(abs(v) for v in (low, high) if v != 0.0) if low * high > 0 else 1e-12, 1e-300)
    exponents = _finite(math.log10(smallest), math.log10(top))
    signs = [s for s in (1.0, -1.0) if (s > 0 and high > 0) or (s < 0 and low < 0)]
    return st.builds(lambda e, s: s * 10.0**e, exponents, st.sampled_from(signs)).filter(
        lambda v: low <= v <= high)


def numbers(setting: spec.Setting, within: tuple[float, float] | None = None,
            valid: bool = False) -> st.SearchStrategy[float]:
    """Floats for a numeric setting, by class: inside the range (near the
    default, and spread over the range), the edges and their neighbours, just
    outside, absurd finite values, nan and inf (``valid``: the first two only).

    ``within`` narrows the values drawn *inside* the range (the edges and
    outside values still come from the setting's own range): a suite on a
    time budget keeps e.g. publish_rate away from 1 Hz, where every check
    would wait a second.
    """
    low = -math.inf if setting.low is None else float(setting.low)
    high = math.inf if setting.high is None else float(setting.high)
    default = float(setting.default)  # type: ignore[arg-type]
    inner_low, inner_high = within if within is not None else (low, high)
    scale = abs(default) or 1.0
    near = _finite(max(inner_low, default - 2.0 * scale), min(inner_high, default + 2.0 * scale))
    edges: list[float] = []
    outside: list[float] = []
    for edge, inward, outward in ((low, math.inf, -math.inf), (high, -math.inf, math.inf)):
        if math.isfinite(edge):
            edges += [edge, math.nextafter(edge, inward)]
            outside += [math.nextafter(edge, outward), edge + math.copysign(max(abs(edge) * 1e-6, 1e-9), outward)]
    if within is not None:
        edges = [v for v in edges if inner_low <= v <= inner_high] or [inner_low, inner_high]
    spread = _log_spread(inner_low, inner_high) if inner_high > inner_low else near
    if valid:
        return st.one_of(near, near, spread, st.sampled_from(edges))
    return st.one_of(
        near, near, near, spread, spread, st.sampled_from(edges), st.sampled_from(edges),
        st.sampled_from(outside or [high]), st.sampled_from(ABSURD), st.sampled_from(NON_FINITE),
    )


def integers(setting: spec.Setting, valid: bool = False) -> st.SearchStrategy[int]:
    """Integers for an integer setting: inside, the edges, just outside, int64's extremes
    (``valid``: inside and the edges only)."""
    low, high = int(setting.low or 0), int(setting.high or 2**31)
    inside = st.one_of(st.integers(low, min(high, low + 20)), st.integers(low, high), st.sampled_from([low, high]))
    if valid:
        return inside
    return st.one_of(inside, st.sampled_from([low - 1, high + 1, 0, -1, *INT64]))


def wrong_types(kind: type) -> st.SearchStrategy[Any]:
    """Values of every parameter type but ``kind`` (None is NOT_SET, which would undeclare it)."""
    candidates: dict[type, st.SearchStrategy[Any]] = {
        bool: st.booleans(),
        int: st.sampled_from([0, 1, 2, -1, *INT64]),
        float: st.sampled_from([0.0, 1.0, NAN, 1e308]),
        str: st.sampled_from(["", "1.0", "nan", "true", "0.7 N"]),
    }
    others = [strategy for other, strategy in candidates.items() if other is not kind]
    arrays = st.sampled_from([[1.0, 2.0], [1, 2], [True], ["a"], [b"\x00"]])
    return st.one_of(*others, st.none(), arrays)


def texts() -> st.SearchStrategy[str]:
    """Any string a message or parameter can carry (no NUL: the middleware's
    strings are C strings, that is DDS's limit, not the node's)."""
    return st.one_of(st.sampled_from(["", "slideway", " ", "/", "a" * 300, "ünïcödé ✓", "$(env HOME)"]),
                     st.text(st.characters(exclude_characters="\x00", exclude_categories=("Cs",)), max_size=40))


def choices(setting: spec.Setting, valid: bool = False) -> st.SearchStrategy[str]:
    """Text for a string setting with choices (``landing_friction``): each choice,
    often, and (unless ``valid``) near misses (case, spaces, a prefix, another
    word) and any text."""
    exact = st.sampled_from(setting.choices)
    if valid:
        return exact
    near = [variant for choice in setting.choices
            for variant in (choice.upper(), choice.capitalize(), f" {choice}", f"{choice} ", choice[:-1])]
    return st.one_of(exact, exact, exact, st.sampled_from([*near, "plastic", "coulomb", "sliding"]), texts())


def setting_values(setting: spec.Setting, within: tuple[float, float] | None = None,
                   valid: bool = False) -> st.SearchStrategy[Any]:
    """Values for a parameter: of its own type (by class, see :func:`numbers`;
    a string with choices: the choices and near misses, :func:`choices`) or of a
    wrong one (``valid``: of its own type, inside its range or one of its choices)."""
    kind = setting.kind
    own: st.SearchStrategy[Any]
    if kind is float:
        own = numbers(setting, within, valid)
    elif kind is int:
        own = integers(setting, valid)
    elif kind is bool:
        own = st.booleans()
    elif setting.choices:
        own = choices(setting, valid)
    else:
        own = texts()
    return own if valid else st.one_of(own, own, own, own, own, own, wrong_types(kind))


# -- parameters -----------------------------------------------------------------------------


def parameter_items(settings: Mapping[str, spec.Setting],
                    within: Mapping[str, tuple[float, float]] | None = None,
                    names: Sequence[str] | None = None, valid: bool = False) -> st.SearchStrategy[tuple[str, Any]]:
    """(name, value) of any parameter of a node (``settings``), of rclpy's
    ``use_sim_time``, or of one it does not declare (``valid``: a declared,
    writable parameter and a value of its type inside its range)."""
    within = within or {}
    chosen = [name for name in names or settings if not (valid and settings[name].start_only)]

    def value_for(name: str) -> st.SearchStrategy[Any]:
        if name in settings:
            return setting_values(settings[name], within.get(name), valid)
        if name == USE_SIM_TIME:
            return st.one_of(st.booleans(), wrong_types(bool))
        return st.one_of(st.floats(), st.booleans(), texts())

    mine = st.sampled_from(chosen)
    name_strategy = mine if valid else st.one_of(*[mine] * 7, st.sampled_from([USE_SIM_TIME, *UNKNOWN_NAMES]))
    return name_strategy.flatmap(lambda name: st.tuples(st.just(name), value_for(name)))


def params(settings: Mapping[str, spec.Setting], within: Mapping[str, tuple[float, float]] | None = None,
           names: Sequence[str] | None = None) -> st.SearchStrategy[Params]:
    """A single parameter set, a SetParameters request of several, or an atomic
    set of several: of any values, or of values each valid alone (whether
    they are together is for the node to tell)."""
    item = parameter_items(settings, within, names)
    valid = parameter_items(settings, within, names, valid=True)

    def several(items: st.SearchStrategy[tuple[str, Any]]) -> st.SearchStrategy[tuple[tuple[str, Any], ...]]:
        return st.lists(items, min_size=2, max_size=5, unique_by=lambda pair: pair[0]).map(tuple)

    return st.one_of(
        st.builds(Params, st.just("set"), item.map(lambda pair: (pair,))),
        st.builds(Params, st.just("set"), several(item)),
        st.builds(Params, st.just("atomic"), several(item)),
        st.builds(Params, st.just("atomic"), several(valid)),
        st.builds(Params, st.just("atomic"), several(valid)),
    )


# -- topics -----------------------------------------------------------------------------------


def _other_fields(message_type: str, used: Sequence[str]) -> dict[str, st.SearchStrategy[Any]]:
    """The fields of a command message the node does not read (header, torque, force.y):
    any finite value; what a node ignores must not matter."""
    if message_type != "geometry_msgs/msg/WrenchStamped":
        return {}
    floats = st.one_of(_finite(-1e6, 1e6), st.sampled_from(ABSURD))
    paths = [p for p in ("wrench.force.x", "wrench.force.y", "wrench.force.z", "wrench.torque.x",
                         "wrench.torque.y", "wrench.torque.z") if p not in used]
    return {
        "header.stamp.sec": st.integers(-(2**31), 2**31 - 1),
        "header.stamp.nanosec": st.integers(0, 2**32 - 1),
        "header.frame_id": texts(),
        **{path: floats for path in paths},
    }


def topic(name: str, within: Mapping[str, tuple[float, float]] | None = None) -> st.SearchStrategy[Topic]:
    """A message on command topic ``name``: each field it carries (from the
    command table) drawn from its setting's classes, the rest of the message anything."""
    entry = COMMANDS[name]
    within = within or {}
    fields = {
        path: numbers(spec.INPUTS[field] if field in spec.INPUTS else getattr(spec, field.upper()),
                      within.get(field))
        for field, path in zip(entry.fields, entry.message_fields)
    }
    return st.builds(Topic, st.just(name),
                     st.fixed_dictionaries({**fields, **_other_fields(entry.message_type, entry.message_fields)}))


def topics(node: str, within: Mapping[str, tuple[float, float]] | None = None) -> st.SearchStrategy[Topic]:
    """A message on any command topic ``node`` consumes (from the command table)."""
    return st.one_of(*[topic(entry.name, within) for entry in consumed_by(node)])


#: A mean-velocity sample's speed: what a slider publishes (|v| up to ~1e-2 m/s at the
#: default case), the extremes of what its accepted inputs can produce, absurd, nan/inf.
SAMPLE_SPEED = spec.Setting("mean_velocity", 0.0002, "m/s", "a mean-velocity sample", -1e3, 1e3)


def mean_velocity_samples() -> st.SearchStrategy[Topic]:
    """A mean_velocity sample (geometry_msgs/TwistStamped) as the controller receives it.

    ``header.stamp`` None means "the next stamp of a plausible plant" (the
    sender fills it in: real time since the start); otherwise any stamp."""
    stamp = st.one_of(st.none(), st.none(), st.none(),
                      st.tuples(st.integers(-(2**31), 2**31 - 1), st.integers(0, 2**32 - 1)))
    other = st.one_of(_finite(-1e3, 1e3), st.sampled_from(ABSURD), st.sampled_from(NON_FINITE))
    return st.builds(Topic, st.just("mean_velocity"), st.fixed_dictionaries(
        {"twist.linear.x": numbers(SAMPLE_SPEED), "header.stamp": stamp, "twist.angular.z": other}))


def bursts(messages: st.SearchStrategy[Topic]) -> st.SearchStrategy[Burst]:
    """A burst: up to 40 different messages, sent up to 30 times over (floods of ~1000)."""
    return st.builds(Burst, st.lists(messages, min_size=1, max_size=40).map(tuple),
                     st.one_of(st.just(1), st.integers(1, 30)))


def waits() -> st.SearchStrategy[Wait]:
    return st.builds(Wait, st.sampled_from([0.05, 0.2, 0.5]))


__all__ = [
    "ABSURD", "NON_FINITE", "SAMPLE_SPEED", "UNKNOWN_NAMES", "USE_SIM_TIME", "Burst", "Params", "Step", "Topic",
    "Wait", "bursts", "choices", "integers", "mean_velocity_samples", "numbers", "parameter_items", "params",
    "setting_values", "topic", "topics", "waits", "wrong_types",
]
