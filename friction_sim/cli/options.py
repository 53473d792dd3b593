"""What every ``friction-sim`` verb is made of: the verb record, the flags and their checks.

Each verb module declares its verbs as :class:`Verb` records (name, help, the
options it adds, the function that runs it); :mod:`friction_sim.cli.main`
only registers them.  Flags come from the one vocabulary
(:mod:`friction_sim.core.model.spec`): :func:`add_flag` makes a Setting an
option checked by its own ``check``; the plant and model options make a
plant through :func:`~friction_sim.core.model.params.plant_from`.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from friction_sim.core.model import spec
from friction_sim.core.model.params import Inputs, SliderParams, plant_from
from friction_sim.errors import ParameterError


class Verb(NamedTuple):
    """One ``friction-sim`` verb: its name, its one-line help, what adds its
    options to its parser, and what runs it (parsed arguments in, exit code out)."""

    name: str
    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


#: The port ``--foxglove`` without a number serves on: Foxglove's usual one.
FOXGLOVE_DEFAULT_PORT = 8765
#: The settings ``--mass --mu --gravity --drive-force --amplitude --frequency``
#: set: the plant and the inputs the slider takes as parameters.
PLANT_OPTIONS = tuple(setting for setting in (*spec.PLANT.values(), *spec.INPUTS.values())
                      if setting.name in spec.SLIDER_NODE)
#: The plant settings ``umap`` takes (``--mu --static-ratio --angle --phase
#: --inclination --restitution --landing-friction``): U = V f/(g mu) depends on
#: them, not on the mass or g.  At their defaults U is Kostek's closed form.
#: (The map's axes are Fd and Pa: the force actuator's.)
MODEL_OPTIONS = tuple(setting for setting in spec.PLANT.values()
                      if setting.name not in ("mass", "gravity", "actuator", *spec.EXCITER))

class _NonFinite(float):
    """A NaN or inf that takes Setting.check's full path: its fast path lets inf
    through a bound left open (``low <= inf <= +inf``)."""


def flag_type(setting: spec.Setting) -> Callable[[str], Any]:
    """An argparse ``type`` that parses a flag's text and checks it with
    ``setting.check``: NaN, inf and out-of-range values are usage errors
    (one line naming the flag, the value and the limit; exit code 2)."""

    def parse(text: str) -> Any:
        try:
            value = setting.kind(text)
        except ValueError:
            value = text  # not a number: check() says what it must be
        if isinstance(value, float) and not math.isfinite(value):
            value = _NonFinite(value)
        try:
            return setting.check(value)
        except ParameterError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    parse.__name__ = setting.name
    return parse


def add_flag(parser: Any, setting: spec.Setting, default: Any = None) -> None:
    """Add ``setting`` as the option ``setting.option`` (dest: its name), parsed
    by :func:`flag_type`; the help gives its meaning, unit, range and default."""
    unit = f" [{setting.unit}]" if setting.dimensioned else ""
    limits = "; ".join(part for part in (setting.range_text(), setting.rule) if part)
    shown = "" if default is None else f"; default {default}" if isinstance(default, str) else f"; default {default:g}"
    metavar = ("{" + ",".join(setting.choices) + "}" if setting.choices
               else setting.option.lstrip("-").replace("-", "_").upper())
    parser.add_argument(setting.option, dest=setting.name, type=flag_type(setting), default=default,
                        metavar=metavar,
                        help=f"{setting.description}{unit}" + (f" ({limits}{shown})" if limits or shown else ""))
    parser.set_defaults(flags={**(parser.get_default("flags") or {}), setting.name: setting.option})


def flag_of(args: argparse.Namespace, name: str) -> str | None:
    """The option that set the value ``name`` (``amplitude_ratio`` -> ``--ratio``), if a flag did."""
    flags: dict[str, str] = getattr(args, "flags", None) or {}
    return flags.get(name)


def add_plant_options(parser: argparse.ArgumentParser) -> None:
    """The model's parameters and inputs as options (flag, default, unit, range
    and meaning from :mod:`friction_sim.core.model.spec`); defaults are the paper's Fig. 2 case."""
    group = parser.add_argument_group("plant (defaults: the paper's Fig. 2 case)")
    for setting in PLANT_OPTIONS:
        add_flag(group, setting, setting.default)


def add_model_options(parser: argparse.ArgumentParser) -> None:
    """The plant settings U depends on (:data:`MODEL_OPTIONS`) as options, at their defaults."""
    group = parser.add_argument_group("model (defaults: Kostek's model, where U has its closed form)")
    for setting in MODEL_OPTIONS:
        add_flag(group, setting, setting.default)


def model(args: argparse.Namespace) -> SliderParams:
    """The plant the model options give (mass and g at their defaults: U does not depend on them)."""
    return plant_from({s.name: getattr(args, s.name) for s in MODEL_OPTIONS})[0]


def plant(args: argparse.Namespace) -> tuple[SliderParams, Inputs]:
    """The plant and inputs the plant options give, checked as the slider would."""
    return plant_from({s.name: getattr(args, s.name) for s in PLANT_OPTIONS})


def add_foxglove(parser: argparse.ArgumentParser) -> None:
    """``--foxglove [PORT]``: serve a Foxglove live view (foxglove_port; PORT
    defaults to Foxglove's usual 8765), checked like the parameter."""
    parser.add_argument("--foxglove", nargs="?", const=FOXGLOVE_DEFAULT_PORT, default=None,
                        type=flag_type(spec.FOXGLOVE_PORT), metavar="PORT",
                        help="serve a Foxglove live view on ws://127.0.0.1:PORT (default PORT "
                             f"{FOXGLOVE_DEFAULT_PORT}; foxglove_address sets another address)")


def _json_ready(value: Any) -> Any:
    """JSON has no inf or NaN: write them as null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _json_ready(item) for key, item in value.items()}
    return value


def print_json(payload: dict[str, Any]) -> None:
    print(json.dumps(_json_ready(payload), allow_nan=False))


def say_saved(figure: Any, path: Path) -> None:
    """Save a figure (at the package's one resolution), creating its folder, and say where."""
    from friction_sim.cli.figures import save_figure

    print(f"wrote {save_figure(figure, path)}")


__all__ = [
    "FOXGLOVE_DEFAULT_PORT", "MODEL_OPTIONS", "PLANT_OPTIONS", "Verb", "add_flag", "add_foxglove",
    "add_model_options", "add_plant_options", "flag_of", "flag_type", "model", "plant", "print_json", "say_saved",
]
