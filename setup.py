from glob import glob

from setuptools import find_packages, setup

package_name = 'friction_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        # Parameter files, scenarios, the Foxglove layout (config/*.foxglove_layout.json) and the
        # calibration example (config/*.csv).
        ('share/' + package_name + '/config', glob('config/*.yaml') + glob('config/*.json') + glob('config/*.csv')),
        # `ros2 launch friction_sim feeder.launch.py` looks in share/<package>/launch.
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    # ROS dependencies (rclpy, message packages) are declared in package.xml
    # and, outside a ROS installation, come from the PyPI wheels listed in
    # requirements.txt, which gives every range (test_package_layout.py checks
    # these against it).  install_requires holds only what rosdep installs on the
    # ROS 2 route: the console scripts a colcon build writes check it at start.
    # The extras are the packages only pip brings (the README's pip line).
    install_requires=['setuptools', 'numpy>=1.26', 'pyyaml>=6.0.1', 'matplotlib>=3.6.3', 'numba>=0.59',
                      'mcap>=1.6', 'zstandard>=0.25', 'rosbags>=0.11.9', 'scipy>=1.11.4'],
    extras_require={
        'sweep': ['dask>=2026.8', 'distributed>=2026.8', 'pyarrow>=25'],
        'live': ['foxglove-sdk>=0.30.3'],
    },
    zip_safe=True,
    python_requires='>=3.10',
    maintainer='friction_sim maintainers',
    maintainer_email='maintainers@friction-sim.dev',
    description=(
        "Exact event-driven stick-slip simulator of a vibratory-feeder slider "
        "after R. Kostek's model, with ROS 2 nodes and MCAP recording."
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'slider = friction_sim.ros.slider:main',
            'controller = friction_sim.ros.controller:main',
            'friction-sim = friction_sim.cli.main:main',
        ],
    },
)
