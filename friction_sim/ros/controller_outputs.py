"""What the controller node sends: the law's decision on its command topics, and diagnostics.

:class:`ControllerOutputs` carries out each decision of the law: Pa on
``excitation_amplitude`` (force actuator), or the drive level on
``drive_level`` (resonant: the inner loop's at a window's end, the steady
gain's otherwise) and the drive frequency on ``excitation_frequency`` when
resonance tracking moves it; in lockstep only a sample's answer carries them
(:mod:`friction_sim.ros.controller_lockstep`).  A new Pa is noted on the
law's sample clock (the plant's answer to the old one is no sample of the
new).  It warns once each time the target becomes unreachable or the drive
runs away, and publishes the status on ``diagnostics``, stamped by the node's
clock (or, in lockstep, the simulation time of the sample last answered).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.clock import ROSClock
from std_msgs.msg import Float64

from friction_sim.core.control.reach import ControlOutput
from friction_sim.core.runtime.controller import RealtimeController
from friction_sim.core.runtime.drive import DriveCommand
from friction_sim.io.messages import key_values, time_msg
from friction_sim.ros.controller_lockstep import LockstepAnswers
from friction_sim.ros.graph import NameWatch
from friction_sim.ros.intake import LostMessages
from friction_sim.ros.run import wall_ns

#: Depth of the output topics' queues.
QOS_DEPTH = 10


class OutputHost(Protocol):
    """What the outputs need of the controller node (:class:`~friction_sim.ros.controller.ControllerNode`)."""

    @property
    def runtime(self) -> RealtimeController: ...
    @property
    def lockstep(self) -> LockstepAnswers | None: ...
    @property
    def ready(self) -> bool: ...
    @property
    def names(self) -> NameWatch: ...
    def get_clock(self) -> Any: ...
    def get_logger(self) -> Any: ...
    def get_fully_qualified_name(self) -> str: ...
    def create_publisher(self, *args: Any, **kwargs: Any) -> Any: ...


class ControllerOutputs:
    """The node's publishers and what it publishes on them (see the module doc)."""

    def __init__(self, host: OutputHost) -> None:
        self._host = host
        self._last_published: float | None = None
        #: Called with each decision carried out.
        self.output_listeners: list[Callable[[ControlOutput], None]] = []
        #: Called with each drive command published (resonant actuator).
        self.drive_listeners: list[Callable[[DriveCommand], None]] = []
        #: The force actuator's command topic and the resonant one's (start-up waits for a listener).
        self.amplitude = host.create_publisher(Float64, "excitation_amplitude", QOS_DEPTH)
        self._diagnostics = host.create_publisher(DiagnosticArray, "diagnostics", QOS_DEPTH)
        self.level = host.create_publisher(Float64, "drive_level", QOS_DEPTH)
        frequency = host.create_publisher(Float64, "excitation_frequency", QOS_DEPTH)
        self._topics = {"excitation_amplitude": self.amplitude, "drive_level": self.level,
                        "excitation_frequency": frequency}

    def publish(self, output: ControlOutput, boundary: float | None = None) -> dict[str, float]:
        """Carry out the law's decision and return it as the values it sets: Pa
        (force actuator), or the drive level (resonant: the inner loop's at a
        window's end ``boundary``, the steady gain's otherwise) and a frequency
        tracking moved.  In real time they are published on their topics; in
        lockstep only a sample's answer carries them (the caller sends it), so
        a decision between samples waits for the next one."""
        host = self._host
        runtime, lockstep = host.runtime, host.lockstep
        if not (host.ready and runtime.active):
            return {}
        if lockstep is not None and boundary is None:  # it acts with the next answer: not clean
            lockstep.changed = lockstep.changed or output.amplitude != self._last_published
            return {}
        control = runtime.control
        acts_at = lockstep.acts_at(boundary) if lockstep is not None and boundary is not None \
            else self._sim_time()
        if output.amplitude != self._last_published:  # the plant's answer to the old Pa is no sample of the new
            control.clock.note_change(wall_ns(), 1.0 / control.frequency, acts_at)
            self._last_published = output.amplitude
        values = self._drive_values(boundary, acts_at) if runtime.drive is not None \
            else {"excitation_amplitude": output.amplitude}
        if lockstep is None:
            for name, value in values.items():
                self._topics[name].publish(Float64(data=value))
        self._warn_on_conditions(output)
        for listener in self.output_listeners:
            listener(output)
        return values

    def _drive_values(self, boundary: float | None, acts_at: float | None) -> dict[str, float]:
        """The drive level (after a frequency tracking moved).  The inner loop
        decides at boundaries only (its model starts from the plant's level in
        force, and plans from there); without it each new Pa is answered at once.
        A window judged by the law must lie after the slideway settled: the
        change is noted while the loop still moves the amplitude."""
        runtime = self._host.runtime
        drive, control = runtime.drive, runtime.control
        assert drive is not None
        if boundary is not None:
            command = runtime.drive_boundary(boundary)
        elif not drive.inner_loop:
            command = runtime.steady_drive()
        else:
            return {}
        assert command is not None
        if drive.inner_loop and not drive.settled:
            control.clock.note_change(wall_ns(), 1.0 / control.frequency,
                                      boundary if self._host.lockstep is None else acts_at)
        for listener in self.drive_listeners:
            listener(command)
        if command.frequency_changed:
            return {"excitation_frequency": command.frequency, "drive_level": command.level}
        return {"drive_level": command.level}

    def _sim_time(self) -> float | None:
        """The simulation time [s] of the node's clock under ``use_sim_time``
        once /clock has come (a paused slider's /clock stands still), else None."""
        clock = self._host.get_clock()
        if not (isinstance(clock, ROSClock) and clock.ros_time_is_active):
            return None
        now = clock.now().nanoseconds
        return now / 1e9 if now > 0 else None

    def _warn_on_conditions(self, output: ControlOutput) -> None:
        """Warn once each time the target becomes unreachable or the drive runs away."""
        warnings, publish = self._host.runtime.news(output)
        for text in warnings:
            self._host.get_logger().warning(text)
        if publish:
            self.publish_diagnostics()

    def publish_diagnostics_timed(self) -> None:
        """Every diagnostics_period of wall time (in lockstep: of simulation time, with the answers)."""
        lockstep = self._host.lockstep
        if lockstep is None or lockstep.stamp_ns == 0:  # (lockstep: until the first answer, stamped 0)
            self.publish_diagnostics()

    def publish_diagnostics(self) -> None:
        """The controller's status on ``diagnostics``, stamped by the node's
        clock (wall time, or /clock under use_sim_time) as the slider's is; in
        lockstep with the simulation time of the sample last answered."""
        host = self._host
        report = host.runtime.status(namesake=host.names.problem, ready=host.ready)
        lockstep = host.lockstep.values() if host.lockstep is not None else {}
        status = DiagnosticStatus(name="controller", hardware_id=host.get_fully_qualified_name(),
                                  level=bytes([report.level]), message=report.message,
                                  values=key_values({**report.values, **lockstep, "messages_lost": LostMessages.count}))
        msg = DiagnosticArray(status=[status])
        if host.lockstep is None:
            msg.header.stamp = host.get_clock().now().to_msg()
        else:
            time_msg(host.lockstep.stamp_ns, msg.header.stamp)
        self._diagnostics.publish(msg)
        if host.lockstep is not None:
            host.lockstep.report(msg)
