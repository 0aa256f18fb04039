"""rclpy helpers of seapup_control that are not nodes: the SIL harness (:mod:`seapup_control.ros.sil`)."""
