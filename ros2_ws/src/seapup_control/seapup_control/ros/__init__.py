"""rclpy helpers of seapup_control that are not nodes: the one-message-per-sample publisher
(:mod:`seapup_control.ros.sample_publisher`) the open-loop and reference-schedule nodes share."""
