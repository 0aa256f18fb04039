"""Starting the live view (``view.py``): the port check agrees with the view's own listener, and the view's
command line survives an empty parameter (issue 40)."""
import socket

import pytest

from seapup_live_view.attach import check_port, ros_arguments
from seapup_live_view.view_relay import Relay


def test_a_port_whose_last_view_just_closed_is_free_at_once():
    """The view closes its viewer's connection first, which lingers (FIN-WAIT/TIME_WAIT) for up to a minute: the
    check and a new view both take the port at once; a port a view still listens on is refused."""
    first = Relay(0, upstream_port=1).start()
    port = first.port
    viewer = socket.create_connection(("127.0.0.1", port), timeout=10.0)
    try:
        with pytest.raises(ValueError, match=f"port {port} on 127.0.0.1 is in use"):
            check_port(port)
        first.stop()   # the view's side closes first: the connection lingers on the port
        assert viewer.recv(1) == b""   # closed by the view
        check_port(port)   # refused for ~60 s before (bound without SO_REUSEADDR)
        second = Relay(port, upstream_port=1).start()
        second.stop()
    finally:
        viewer.close()


@pytest.mark.parametrize("port", [0, 65536, -1])
def test_a_port_out_of_range_is_refused(port):
    with pytest.raises(ValueError, match="must be 1..65535"):
        check_port(port)


def test_an_empty_parameter_override_is_passed_as_the_empty_string():
    argv = ["live_view", "--ros-args", "-p", "port:=8765", "-p", "vehicle:=baseline", "-p", "environment_file:=",
            "--param", "x:=", "-r", "a:=b"]
    assert ros_arguments(argv) == ["live_view", "--ros-args", "-p", "port:=8765", "-p", "vehicle:=baseline",
                                   "-p", "environment_file:=''", "--param", "x:=''", "-r", "a:=b"]
    # outside --ros-args nothing is touched; a remap with an empty target is not a parameter
    assert ros_arguments(["x", "-p", "a:="]) == ["x", "-p", "a:="]
    assert ros_arguments(["x", "--ros-args", "-r", "a:="]) == ["x", "--ros-args", "-r", "a:="]


def test_rcl_takes_the_rewritten_empty_override_as_an_empty_string():
    """The independent truth: rcl's own parser, which refuses ``environment_file:=`` outright."""
    import rclpy
    from rclpy.context import Context
    argv = ["live_view", "--ros-args", "-p", "environment_file:="]
    refused = Context()
    with pytest.raises(Exception, match="environment_file:="):
        rclpy.init(args=argv, context=refused, domain_id=0)
    refused.try_shutdown()
    context = Context()
    rclpy.init(args=ros_arguments(argv), context=context, domain_id=0)
    try:
        from rclpy.node import Node
        node = Node("live_view_args", context=context, automatically_declare_parameters_from_overrides=True,
                    start_parameter_services=False, enable_rosout=False)
        parameter = node.get_parameter("environment_file")
        assert (parameter.type_, parameter.value) == (parameter.Type.STRING, "")
        node.destroy_node()
    finally:
        context.try_shutdown()
