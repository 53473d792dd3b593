"""A slider in lockstep and its controller in one process, linked without DDS.

In lockstep the slider and the controller take turns: the slider publishes a
``mean_velocity`` sample (and the accelerometer's readings up to it), the
controller answers it on ``control_answer``, and only then does simulation time
go on (:mod:`friction_sim.core.runtime.lockstep`).  Through DDS every turn costs
two deliveries and two thread wake-ups, each more than both nodes' work for the
period they let the slider simulate.  When both nodes live in one process (an
experiment run in process, the ``feeder`` executable) they find each other here
and take their turns in the slider's thread: the slider hands the controller
its samples and readings, the controller hands back its answer message, and the
slider takes it as if it had come on ``control_answer``.  The same values in
the same order: the recording is the same bits as through DDS.  rclcpp calls
this intra-process communication; rclpy has none, hence this module.

They find each other by their context and the fully resolved names of the three
topics of the turn (remapping applied), so nodes that would not hear each other
on DDS are never linked.  The link is made when the controller starts to answer
(the slider offers it when its lockstep loop starts), and it is undone when
either side goes; a controller in another process keeps using the topics.

The topics still carry the turn for anyone else: the slider publishes every
sample as always (and the readings whenever someone reads them), and a linked
controller publishes its answer too whenever someone besides its slider
listens.  The slider then takes the copy that comes over DDS as a repeat
(``lockstep_stale_answers``, a wall-clock figure, left out of digests).  The
controller's diagnostics, stamped with the sample they answer, reach the
slider's recording through the link too (and the copy on DDS is not recorded):
over DDS the first ones could go out before the recording's reader had
matched the controller, and be lost in one run but not the next.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol


@dataclass(frozen=True)
class TurnTopics:
    """The fully resolved names of a lockstep turn's topics (both ends must agree on each)."""

    samples: str  # mean_velocity
    answers: str  # control_answer
    readings: str  # accelerometer


class LinkedAnswers(Protocol):
    """The controller's side of a link (:class:`~friction_sim.ros.controller_lockstep.LockstepAnswers`)."""

    def deliver(self, samples: Sequence[tuple[int, float]], readings: Sequence[tuple[int, float]]) -> None:
        """Take samples (stamp [ns], mean speed [m/s]) and readings (stamp [ns], normal
        acceleration [m/s^2]), each in order, and answer what can be answered."""


class Link:
    """One slider's offer of a link, and the controller linked to it (if any)."""

    def __init__(self, context: Any, topics: TurnTopics, wake: Callable[[], None]) -> None:
        self.context, self.topics = context, topics
        #: The answer messages (control_answer's JointState) for the slider, oldest first.
        self.answers: deque[Any] = deque()
        self._wake = wake
        #: The thread of the slider's loop: an answer given in it needs no wake-up.
        self.slider_thread: threading.Thread | None = None
        #: The linked controller's answers (None: none linked), and how many have been linked.
        self.controller: LinkedAnswers | None = None
        self.generation = 0
        #: The linked controller's node (its fully qualified name: its diagnostics' hardware_id).
        self.controller_name = ""
        #: The linked controller's diagnostics (DiagnosticArray), oldest first, for the slider's recording.
        self.reports: deque[Any] = deque()

    def answer(self, msg: Any) -> None:
        """The controller's answer message: queued for the slider, which is woken if it sleeps."""
        self.answers.append(msg)
        if threading.current_thread() is not self.slider_thread:
            self._wake()


_lock = threading.Lock()
_offers: dict[tuple[int, TurnTopics], Link] = {}


def offer(context: Any, topics: TurnTopics, wake: Callable[[], None]) -> Link | None:
    """The slider's offer (None if another slider of this process offers the same topics:
    a name clash, left to DDS as it would be without the link)."""
    key = (id(context), topics)
    with _lock:
        if key in _offers:
            return None
        link = _offers[key] = Link(context, topics, wake)
    return link


def withdraw(link: Link) -> None:
    """The slider goes: no controller is handed anything through ``link`` any more."""
    with _lock:
        if _offers.get((id(link.context), link.topics)) is link:
            del _offers[(id(link.context), link.topics)]
        link.controller = None


def _free(context: Any, topics: TurnTopics) -> Link | None:
    """The offer of ``topics`` in ``context`` with no controller linked yet (lock held)."""
    link = _offers.get((id(context), topics))
    return link if link is not None and link.context is context and link.controller is None else None


def linkable(context: Any, topics: TurnTopics) -> bool:
    """Whether a slider of this process offers ``topics`` with no controller linked yet."""
    with _lock:
        return _free(context, topics) is not None


def attach(context: Any, topics: TurnTopics, answers: LinkedAnswers, name: str = "") -> Link | None:
    """Link the controller's ``answers`` (its node ``name``) to the slider of this process
    that offers ``topics`` (None: there is none, or it has a controller already)."""
    with _lock:
        link = _free(context, topics)
        if link is None:
            return None
        link.controller = answers
        link.controller_name = name
        link.generation += 1
    return link


def detach(link: Link, answers: LinkedAnswers) -> None:
    """The controller goes: its slider hands it nothing more."""
    with _lock:
        if link.controller is answers:
            link.controller = None


__all__ = ["Link", "LinkedAnswers", "TurnTopics", "attach", "detach", "linkable", "offer", "withdraw"]
