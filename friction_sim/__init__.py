"""friction_sim: exact stick-slip simulation of a vibratory-feeder slider.

The physics core (:mod:`friction_sim.core.engine.single`) and the U relation
(:mod:`friction_sim.core.meanspeed.urelation`) need only numpy; the ROS 2 nodes live in
:mod:`friction_sim.ros` and import rclpy only when used.
"""

from friction_sim.core.engine.single import Event, EventKind, Mode, Slider, SliderState, Trajectory
from friction_sim.core.meanspeed.urelation import amplitude_ratio_for, u_map
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import FrictionSimError, ParameterError, RecordingError

__version__ = "0.1.0"

__all__ = [
    "Event", "EventKind", "FrictionSimError", "Inputs", "Mode", "ParameterError", "RecordingError",
    "Slider", "SliderParams", "SliderState", "Trajectory", "amplitude_ratio_for", "u_map",
]
