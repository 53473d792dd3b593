"""friction_sim: exact stick-slip simulation of a vibratory-feeder slider.

The physics core (:mod:`friction_sim.core.slider`) and the U relation
(:mod:`friction_sim.core.urelation`) need only numpy; the ROS 2 nodes live in
:mod:`friction_sim.ros` and import rclpy only when used.
"""

from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.slider import Event, EventKind, Mode, Slider, SliderState, Trajectory
from friction_sim.core.urelation import amplitude_ratio_for, u_map
from friction_sim.errors import FrictionSimError, ParameterError, RecordingError

__version__ = "0.1.0"

__all__ = [
    "Event", "EventKind", "FrictionSimError", "Inputs", "Mode", "ParameterError", "RecordingError",
    "Slider", "SliderParams", "SliderState", "Trajectory", "amplitude_ratio_for", "u_map",
]
