"""What the nodes watch in the ROS graph: another node of their own name.

:class:`NameWatch` warns while another node has the same fully qualified name
(both would take the same commands).
"""

from __future__ import annotations

from rclpy.clock import Clock, ClockType
from rclpy.node import Node


class NameWatch:
    """Warns while another node in the graph has ``node``'s fully qualified name.

    Two nodes with one name both answer the same parameter services and
    publish on the same topics (interleaved, stamps going backwards).  ROS 2
    does not prevent it, so the graph is checked after discovery had time to
    see the others (at ``first`` s) and then every ``period`` s; :attr:`problem`
    is the text diagnostics show while it lasts ('' otherwise).
    """

    def __init__(self, node: Node, period: float = 1.0, first: float = 0.5) -> None:
        self._node = node
        self.problem = ""
        self._period = period
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = node.create_timer(first, self._first, clock=steady)

    def _first(self) -> None:
        self._node.destroy_timer(self._timer)
        self._timer = self._node.create_timer(self._period, self.check,
                                              clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.check()

    def check(self) -> str:
        """Look at the graph now; warn when a namesake appears, say when it is gone."""
        node = self._node
        name, namespace = node.get_name(), node.get_namespace()
        count = sum(1 for n, ns in node.get_node_names_and_namespaces() if n == name and ns == namespace)
        fqn = node.get_fully_qualified_name()
        problem = ""
        if count > 1:
            others = "another node" if count == 2 else f"{count - 1} other nodes"
            problem = f"{others} named {fqn} in the graph: both take the same commands and parameter sets"
        if problem and not self.problem:
            node.get_logger().warning(f"{problem}; give this one another name (--ros-args -r __node:=NAME "
                                      "or -r __ns:=/NAMESPACE)")
        elif self.problem and not problem:
            node.get_logger().info(f"the name {fqn} is unique again")
        self.problem = problem
        return problem
