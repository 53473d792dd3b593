"""Start a feeder: the slider and its mean-speed controller, in one namespace.

    ros2 launch friction_sim feeder.launch.py namespace:=/feeder1 log_path:=run.mcap \
        foxglove_port:=8765 use_sim_time:=true

Arguments (``ros2 launch friction_sim feeder.launch.py --show-args`` lists them):

* ``namespace``: where both nodes live ('' = the root); all their names are
  relative, so ``/feeder1`` gives ``/feeder1/pose``, ``/feeder1/slider``, ...
* ``slider_params``, ``controller_params``: ROS 2 parameter files (default: the
  installed ``config/slider.yaml`` and ``config/controller.yaml``).
* ``log_path``: record the run to this MCAP file ('' = no recording).
* ``foxglove_port``: serve the Foxglove live view on this port (0 = off).
* ``use_sim_time``: the controller follows the slider's simulation time on /clock.

log_path, foxglove_port and use_sim_time are set after the parameter files, so
they win over what the files say.  Every parameter name here is one of
``friction_sim.core.model.spec`` (or ROS's own ``use_sim_time``); test/test_launch_file.py
checks that, and that every argument is declared and used.
"""

# ruff takes this repository's launch/ folder for the `launch` package (first party) and would split
# the block; both are ROS 2 packages from the install.
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

PACKAGE = 'friction_sim'


def generate_launch_description() -> LaunchDescription:
    """The launch arguments, then the slider and the controller."""
    namespace = LaunchConfiguration('namespace')
    use_sim_time = LaunchConfiguration('use_sim_time')
    config = FindPackageShare(PACKAGE)
    arguments = [
        DeclareLaunchArgument('namespace', default_value='',
                              description="namespace of both nodes ('' = the root)"),
        DeclareLaunchArgument('slider_params', default_value=PathJoinSubstitution([config, 'config', 'slider.yaml']),
                              description='parameter file of the slider'),
        DeclareLaunchArgument('controller_params',
                              default_value=PathJoinSubstitution([config, 'config', 'controller.yaml']),
                              description='parameter file of the controller'),
        DeclareLaunchArgument('log_path', default_value='',
                              description="record the run to this MCAP file ('' = no recording)"),
        DeclareLaunchArgument('foxglove_port', default_value='0',
                              description='serve the Foxglove live view on this TCP port (0 = off; usually 8765)'),
        DeclareLaunchArgument('use_sim_time', default_value='false', choices=['true', 'false'],
                              description='controller on the slider\'s simulation time (/clock)'),
    ]
    slider = Node(
        package=PACKAGE, executable='slider', name='slider', namespace=namespace, output='screen',
        parameters=[
            LaunchConfiguration('slider_params'),
            {
                'log_path': ParameterValue(LaunchConfiguration('log_path'), value_type=str),
                'foxglove_port': ParameterValue(LaunchConfiguration('foxglove_port'), value_type=int),
                # The slider is the clock source: its simulation time comes from the exact
                # core, paced by the monotonic wall clock, and publish_clock puts it on
                # /clock for the nodes that follow it (use_sim_time).  use_sim_time itself
                # would only make the slider read its own /clock back, so it is not set.
                'publish_clock': ParameterValue(use_sim_time, value_type=bool),
            },
        ],
    )
    controller = Node(
        package=PACKAGE, executable='controller', name='controller', namespace=namespace, output='screen',
        parameters=[
            LaunchConfiguration('controller_params'),
            # The controller's plant_node (default 'slider') is relative: the slider above.
            {'use_sim_time': ParameterValue(use_sim_time, value_type=bool)},
        ],
    )
    return LaunchDescription([*arguments, slider, controller])
