"""``./seapup teleop``: fly the vehicle by hand from the keyboard (seapup_control.manual).

Reads keys from this terminal (raw mode, restored on exit whatever ends it) and publishes the pilot's demand as
a ``geometry_msgs/Twist`` (REP-103 ``base_link``) on ``/seapup/pilot/cmd_vel`` at ``rate`` Hz of the wall clock,
the topic a ``manual`` velocity controller flies (and Foxglove's Teleop panel can publish too). Stopping the
node stops the messages: the manual law then brings the vehicle to rest after its silence timeout.
"""
from __future__ import annotations

import os
import select
import sys

from geometry_msgs.msg import Twist
from rclpy.node import Node

from seapup_common.ros.node import COMMAND_QOS, declare_from_package_file, run_node
from seapup_common.topics import NAMESPACE
from seapup_control.manual import TELEOP_HELP, TeleopKeys

__all__ = ["TeleopNode", "main"]


class TeleopNode(Node):
    """rclpy shell around :class:`~seapup_control.manual.TeleopKeys` (module docstring)."""

    def __init__(self, keys_fd: int | None = None, **kwargs):
        super().__init__("teleop", namespace=NAMESPACE, **kwargs)
        p = declare_from_package_file(self, "seapup_control", "teleop.yaml", section="teleop", ranges={
            "rate": (1.0, 100.0), "linear_step": (0.001, 1.0), "angular_step": (0.001, 1.0),
            "max_linear": (0.01, 2.0), "max_angular": (0.01, 3.0)})
        self.keys = TeleopKeys(p["linear_step"], p["angular_step"], p["max_linear"], p["max_angular"])
        self.fd = keys_fd   # None: this process's terminal, read at the first tick
        self.publisher = self.create_publisher(Twist, "pilot/cmd_vel", COMMAND_QOS)
        self.sent = 0
        self.create_timer(1.0 / p["rate"], self._tick)
        print(f"seapup teleop: {TELEOP_HELP}", file=sys.stderr, flush=True)

    def _tick(self) -> None:
        fd = sys.stdin.fileno() if self.fd is None else self.fd
        while select.select([fd], [], [], 0.0)[0]:
            data = os.read(fd, 64)
            if not data:             # end of input: quit
                self.keys.quit = True
                break
            for key in data.decode(errors="replace"):
                if self.keys.press(key) and not self.keys.quit:
                    x, y, z = self.keys.linear()
                    print(f"\rseapup teleop: forward {x:+.2f} left {y:+.2f} up {z:+.2f} m/s, "
                          f"turn {self.keys.angular()[2]:+.2f} rad/s   ", end="", file=sys.stderr, flush=True)
        if self.keys.quit:
            raise KeyboardInterrupt   # ends the node on purpose (run_node): exit 0
        msg = Twist()
        msg.linear.x, msg.linear.y, msg.linear.z = self.keys.linear()
        msg.angular.x, msg.angular.y, msg.angular.z = self.keys.angular()
        self.publisher.publish(msg)
        self.sent += 1


def main(args=None) -> int:
    if not os.isatty(sys.stdin.fileno()):
        print("seapup teleop: error: it reads keys from a terminal, and stdin is not one", file=sys.stderr)
        return 1
    import termios
    import tty
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd)            # keys as they are pressed, no echo; Ctrl-C still a signal
        return run_node(TeleopNode, args)
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
        print("", file=sys.stderr)


if __name__ == "__main__":
    raise SystemExit(main())
