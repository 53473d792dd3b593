"""``friction-sim replay FILE``: verify, republish, export or plot a recording.

Without an action it describes the recording (``ros2 bag info``-like,
with the file's ``external_wrench`` convention).  Every action streams the
file (memory bounded whatever its length).  A file written before the
convention was marked (force.z > 0 pressed the slider on the track) is
verified and republished in today's (force.z > 0 lifts); ``--csv`` writes
its messages as recorded.
Exit codes: 0 ok, 1 when ``--verify`` finds a difference; a file that
cannot be used, and ``--verify`` of a file whose recorder dropped messages,
raise :class:`~friction_sim.errors.RecordingError` (the CLI prints it as
one line and exits 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from friction_sim.cli.options import Verb, add_flag
from friction_sim.cli.progress import TerminalProgress
from friction_sim.core.model import spec
from friction_sim.errors import RecordingError
from friction_sim.experiment.verify import DEFAULT_TOLERANCE, verify
from friction_sim.io.reader import Recording, read_recording

EXIT_OK, EXIT_MISMATCH, EXIT_ERROR = 0, 1, 2

#: The numeric options, checked like every other setting (NaN, inf and absurd values are usage errors).
TOLERANCE = spec.Setting("tolerance", DEFAULT_TOLERANCE, "-", "relative tolerance of --verify", 1e-16, 1e-2)
RATE = spec.Setting("rate", 1.0, "-", "playback rate factor for --publish", 1e-3, 1e3)
DELAY = spec.Setting("delay", 0.0, "s", "with --publish: seconds to wait before playing", 0.0, 3600.0)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``friction-sim replay FILE ...``."""
    parser.add_argument("file", type=Path, help="the recording (.mcap)")
    parser.add_argument("--verify", action="store_true",
                        help="re-simulate from the recorded parameters and commands and compare with the "
                             "recorded states (exit 1 if they differ by more than --tolerance; a file whose "
                             "recorder dropped messages is refused)")
    add_flag(parser, TOLERANCE, TOLERANCE.default)
    parser.add_argument("--publish", action="store_true", help="republish the messages on their topics")
    add_flag(parser, RATE, RATE.default)
    parser.add_argument("--loop", action="store_true", help="with --publish: start over at the end")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC", help="with --publish/--csv: only these topics")
    parser.add_argument("--namespace", default="", help="with --publish: namespace of the published topics")
    add_flag(parser, DELAY, DELAY.default)
    parser.add_argument("--csv", type=Path, metavar="DIR", help="write one CSV per topic into DIR")
    parser.add_argument("--plot", type=Path, metavar="PNG",
                        help="draw position, velocity, friction force and R with the commands marked")


def run(args: argparse.Namespace) -> int:
    """Run the replay subcommand; 0 ok, 1 when --verify finds a difference.
    Raises RecordingError for a file that cannot be used."""
    recording = read_recording(args.file)
    note = recording.recovery_note()
    if note:
        print(note, file=sys.stderr)
    code = EXIT_OK
    if args.verify:
        code = _verify(recording, args.tolerance)
    if args.csv is not None:
        _csv(recording, args.csv, getattr(args, "topics", None))
    if args.plot is not None:
        _plot(recording, args.plot)
    if args.publish:
        _publish(recording, args)
    if not (args.verify or args.csv is not None or args.plot is not None or args.publish):
        for line in recording.info_lines():
            print(line)
    return code


def _verify(recording: Recording, tolerance: float) -> int:
    """Print the verify report; EXIT_MISMATCH if it did not pass."""
    result = verify(recording, tolerance)
    for line in result.lines():
        print(line)
    return EXIT_OK if result.passed else EXIT_MISMATCH


def _csv(recording: Recording, directory: Path, topics: list[str] | None) -> None:
    """Write the CSV files and say so."""
    from friction_sim.io.export import export_csv

    paths = export_csv(recording, directory, topics)
    print(f"wrote {len(paths)} CSV files to {directory}")


def _plot(recording: Recording, path: Path) -> None:
    """Draw the figure to ``path`` and say so."""
    from friction_sim.cli.figures import save_figure
    from friction_sim.cli.recording_figure import plot

    figure = plot(recording)
    try:
        save_figure(figure, path)
    except OSError as error:
        raise RecordingError(f"cannot write {path}: {error.strerror or error}") from None
    print(f"wrote {path}")


def _publish(recording: Recording, args: argparse.Namespace) -> None:
    """Republish the recording and say how much went out."""
    from friction_sim.ros.republisher import publish

    result = publish(recording, rate=args.rate, loop=args.loop, topics=args.topics,
                     namespace=args.namespace, delay=getattr(args, "delay", 0.0),
                     progress=TerminalProgress(tty_interval=0.1))
    print(f"published {result.messages} messages"
          + (f" in {result.loops} loops" if args.loop else "")
          + (" (interrupted)" if result.interrupted else ""))


VERBS = (Verb("replay", "verify, republish, export or plot a recording", add_arguments, run),)

__all__ = ["VERBS", "add_arguments", "run"]
