"""The wire contract: topic names, message types and QoS (``contract``), the conversions between messages
and the cores' plain values (``conversions``; the point clouds in ``clouds``, the tables in ``tables``; a
hand-written CDR codec for the hot topics), the robot and field description every process agrees on
(``robot_config``), the header-stamp rule (``stamps``) and where installed packages keep their shared files
(``ament_index``).

This is what a robot-side node must import to speak to the others, so it is kept small and imports only
rclpy's message packages: nothing from ``runtime``, ``ssl``, ``tools`` or the other packages. Anyone may
import it.
"""
