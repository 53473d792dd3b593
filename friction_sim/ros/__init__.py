"""ROS 2 nodes: thin adapters between topics and the exact core (need rclpy)."""
