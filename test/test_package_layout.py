"""The repository is a well-formed ROS 2 ament_python package.

These tests check what ROS tooling sees: package.xml as parsed by catkin_pkg,
the package as discovered by ``colcon list``, and the install tree produced by
``colcon build`` (console scripts where ``ros2 run`` looks for them, the
ament index marker, package.xml and the default parameters file).
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PKG = 'friction_sim'
COLCON = Path(sys.executable).parent / 'colcon'



def test_colcon_is_installed_with_the_dev_dependencies() -> None:
    assert COLCON.exists(), f'colcon (requirements-dev.txt) is missing next to {sys.executable}'


def _colcon_env(tmp_path: Path) -> dict:
    env = dict(os.environ)
    # Hermetic colcon: no user-level defaults/mixins, logs outside the repo.
    env['COLCON_HOME'] = str(tmp_path / 'colcon_home')
    env['COLCON_LOG_PATH'] = str(tmp_path / 'log')
    env.pop('COLCON_DEFAULTS_FILE', None)
    return env


def _run(cmd: list, tmp_path: Path, timeout: float) -> subprocess.CompletedProcess:
    proc = subprocess.run(
        [str(c) for c in cmd], cwd=REPO, env=_colcon_env(tmp_path),
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, timeout=timeout)
    assert proc.returncode == 0, (
        f'{" ".join(map(str, cmd))} exited {proc.returncode}:\n{proc.stdout}')
    return proc


def test_package_xml_parses_with_catkin_pkg():
    from catkin_pkg.package import parse_package

    pkg = parse_package(str(REPO / 'package.xml'))  # validates the manifest
    assert pkg.name == PKG
    assert pkg.package_format == 3
    assert pkg.version == '0.1.0'
    assert pkg.get_build_type() == 'ament_python'
    assert pkg.licenses == ['Apache-2.0']
    assert pkg.maintainers, 'package.xml needs a maintainer'
    for m in pkg.maintainers:
        assert m.email and re.fullmatch(r'[^@\s]+@[^@\s]+\.[A-Za-z]{2,}', m.email), m.email
    exec_deps = {d.name for d in pkg.exec_depends}
    for dep in ('rclpy', 'std_msgs', 'geometry_msgs', 'diagnostic_msgs', 'rosgraph_msgs'):
        assert dep in exec_deps, f'missing <exec_depend>{dep}</exec_depend>'


def test_resource_marker_and_config_exist():
    assert (REPO / 'resource' / PKG).is_file()
    assert (REPO / 'config' / 'slider.yaml').is_file()
    assert (REPO / PKG / 'py.typed').is_file()


def test_default_params_file_is_ros2_params_form():
    import yaml
    data = yaml.safe_load((REPO / 'config' / 'slider.yaml').read_text())
    params = data['/**']['ros__parameters']
    assert params['mass'] == 1.0 and isinstance(params['mass'], float)
    assert params['mu'] == 0.1
    assert params['gravity'] == 10.0
    assert params['drive_force'] == 0.7
    assert params['excitation_amplitude'] == 5.0
    assert params['excitation_frequency'] == 50.0
    assert params['publish_rate'] == 1000.0
    assert params['real_time_factor'] == 1.0
    assert params['publish_clock'] is False
    assert params['mean_window_periods'] == 1
    assert params['frame_id'] == 'slideway'


def test_colcon_list_finds_ament_python_package(tmp_path):
    proc = _run([COLCON, '--log-base', tmp_path / 'log', 'list', '--base-paths', REPO],
                tmp_path, timeout=120)
    rows = [line.split('\t') for line in proc.stdout.splitlines() if '\t' in line]
    assert [PKG, str(REPO), '(ros.ament_python)'] in rows, proc.stdout


@pytest.mark.timeout(300)
def test_colcon_build_install_layout(tmp_path):
    before = {p.name for p in REPO.iterdir()}
    build, install, log = tmp_path / 'build', tmp_path / 'install', tmp_path / 'log'
    _run([COLCON, '--log-base', log, 'build',
          '--base-paths', REPO, '--build-base', build, '--install-base', install],
         tmp_path, timeout=280)

    prefix = install / PKG
    for script in ('slider', 'controller', 'friction-sim'):
        exe = prefix / 'lib' / PKG / script
        assert exe.is_file(), f'missing console script {exe}'
        assert os.access(exe, os.X_OK), f'{exe} is not executable'
    assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PKG).is_file()
    assert (prefix / 'share' / PKG / 'package.xml').is_file()
    assert (prefix / 'share' / PKG / 'config' / 'slider.yaml').is_file()
    # Where `ros2 launch friction_sim feeder.launch.py` and its default parameter files look,
    # and the Foxglove layout the README points to.
    assert (prefix / 'share' / PKG / 'launch' / 'feeder.launch.py').is_file()
    assert (prefix / 'share' / PKG / 'config' / 'controller.yaml').is_file()
    assert (prefix / 'share' / PKG / 'config' / 'friction_sim.foxglove_layout.json').is_file()
    assert (prefix / 'share' / PKG / 'config' / 'calibration_example.csv').is_file()

    # The build must not leave anything behind in the source tree.  (Only
    # colcon/setuptools artefacts are checked: other files may legitimately
    # appear while tests run.)
    after = {p.name for p in REPO.iterdir()}
    leftovers = sorted(n for n in after - before
                       if n in ('build', 'install', 'log') or n.endswith('.egg-info'))
    assert not leftovers, f'colcon build left {leftovers} in the repo'
    shutil.rmtree(tmp_path, ignore_errors=True)


# Each runtime requirement (requirements.txt) and the rosdep keys that bring it on a
# ROS 2 Jazzy install: ROS packages by their own names, Python packages by the keys
# of rosdep's python.yaml (ros/rosdistro, checked at 8468e88: python3-numpy,
# python3-yaml, python3-matplotlib, python3-numba, python3-scipy; pip keys mcap-ros2-support, which installs mcap,
# and python3-rosbags-pip).  A new requirement fails this test until it is mapped.
ROSDEP_KEYS = {
    'ros-jazzy-rclpy': {'rclpy', 'rcl_interfaces', 'builtin_interfaces', 'rosgraph_msgs',
                        'ament_index_python'},
    'ros-jazzy-common-interfaces': {'std_msgs', 'geometry_msgs', 'diagnostic_msgs', 'std_srvs'},
    'ros-jazzy-sensor-msgs': {'sensor_msgs'},
    'numpy': {'python3-numpy'},
    'pyyaml': {'python3-yaml'},
    'mcap': {'mcap-ros2-support'},
    'zstandard': {'mcap-ros2-support'},  # mcap's own dependency: the same pip key brings it
    'rosbags': {'python3-rosbags-pip'},
    'matplotlib': {'python3-matplotlib'},
    'numba': {'python3-numba'},
    'scipy': {'python3-scipy'},
    # Sweeps only: rosdep has no key for these (ros/rosdistro 8468e88); package.xml says to pip-install them.
    'dask': set(),
    'distributed': set(),
    'pyarrow': set(),
    # Live view only: rosdep has no key for the PyPI foxglove-sdk (requirements.txt says to pip-install it).
    'foxglove-sdk': set(),
}
#: Exec dependencies that only `ros2 launch` on a real install needs (launch/feeder.launch.py); PyPI has neither.
LAUNCH_ONLY = {'launch', 'launch_ros'}


def _requirements() -> set:
    names = set()
    for line in (REPO / 'requirements.txt').read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            names.add(re.split(r'[\[<>=!~; ]', line, maxsplit=1)[0].lower())
    return names


def test_package_xml_declares_every_runtime_requirement_by_a_rosdep_key():
    from catkin_pkg.package import parse_package

    exec_deps = {d.name for d in parse_package(str(REPO / 'package.xml')).exec_depends}
    requirements = _requirements()
    assert requirements == set(ROSDEP_KEYS), 'map each requirements.txt entry to its rosdep keys here'
    for requirement in sorted(requirements):
        missing = ROSDEP_KEYS[requirement] - exec_deps
        assert not missing, f'{requirement} (requirements.txt) needs <exec_depend> {sorted(missing)}'
    assert exec_deps >= LAUNCH_ONLY, 'the launch file needs <exec_depend> launch and launch_ros'
    declared = set().union(*ROSDEP_KEYS.values(), LAUNCH_ONLY)
    assert exec_deps <= declared, f'package.xml declares what requirements.txt lacks: {exec_deps - declared}'


def _setup_requirements() -> list:
    """install_requires and every extra of setup.py (read as literals: setup.py itself runs setup())."""
    import ast

    call = next(node for node in ast.walk(ast.parse((REPO / 'setup.py').read_text()))
                if isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'setup')
    wanted = ('install_requires', 'extras_require')
    options = {k.arg: ast.literal_eval(k.value) for k in call.keywords if k.arg in wanted}
    return options['install_requires'] + [r for extra in options['extras_require'].values() for r in extra]


def test_setup_py_declares_the_ranges_of_requirements_txt():
    """Each Python requirement of setup.py (install_requires and extras) has the range
    requirements.txt gives it; together they cover every non-ROS entry of requirements.txt."""
    from packaging.requirements import Requirement

    declared = {}
    for line in (REPO / 'requirements.txt').read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        if line:
            requirement = Requirement(line)
            declared[requirement.name.lower()] = requirement.specifier
    in_setup = {Requirement(r).name.lower(): Requirement(r).specifier for r in _setup_requirements()}
    in_setup.pop('setuptools')
    assert set(in_setup) == {name for name in declared if not name.startswith('ros-jazzy-')}
    for name, specifier in in_setup.items():
        assert specifier == declared[name], f'setup.py says {name}{specifier}, requirements.txt {name}{declared[name]}'
