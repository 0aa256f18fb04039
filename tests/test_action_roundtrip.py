"""An action round trip on seapup_msgs/action/SelfTest in a private context.

Server and client live in one process on the test's own domain; the server
sends feedback for each of the four thrusters and succeeds with a result the
client checks field by field.
"""
import rclpy
from rclpy.action import ActionClient, ActionServer, CancelResponse
from rclpy.executors import SingleThreadedExecutor
from seapup_msgs.action import SelfTest


async def execute(goal_handle):
    for i in range(4):
        goal_handle.publish_feedback(SelfTest.Feedback(thruster=i, progress=(i + 1) / 4, phase="step",
                                                       velocity=[0.1 * i, 0.0, 0.0, 0.0]))
    goal_handle.succeed()
    result = SelfTest.Result(success=True, message=f"stepped by {goal_handle.request.step}")
    result.b1_inverse = list(goal_handle.request.operating_points) * 16
    return result


def test_self_test_action_round_trip(ros_context, spin):
    server_node = rclpy.create_node("self_test_server", context=ros_context)
    client_node = rclpy.create_node("self_test_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(server_node)
    executor.add_node(client_node)
    ActionServer(server_node, SelfTest, "/seapup/self_test", execute_callback=execute,
                 cancel_callback=lambda _: CancelResponse.ACCEPT)
    client = ActionClient(client_node, SelfTest, "/seapup/self_test")
    assert spin(executor, client.server_is_ready, 10.0)
    # server_is_ready covers the services only; feedback is a volatile topic that
    # is lost until the client's feedback subscription has matched.
    assert spin(executor, lambda: server_node.count_subscribers("/seapup/self_test/_action/feedback") > 0, 10.0)

    feedback = []
    send = client.send_goal_async(SelfTest.Goal(operating_points=[0.5], step=0.14, sample_period=0.2),
                                  feedback_callback=lambda fb: feedback.append(fb.feedback))
    assert spin(executor, send.done, 10.0)
    handle = send.result()
    assert handle.accepted
    # rclpy stops delivering feedback once the result has arrived, so take the
    # feedback first; the server keeps the result until it is asked for.
    assert spin(executor, lambda: len(feedback) == 4, 10.0)
    result_future = handle.get_result_async()
    assert spin(executor, result_future.done, 10.0)
    response = result_future.result()
    assert response.result.success and response.result.message == "stepped by 0.14"
    assert list(response.result.b1_inverse) == [0.5] * 16
    assert [f.thruster for f in feedback] == [0, 1, 2, 3] and feedback[2].velocity[0] == 0.2
    assert feedback[-1].progress == 1.0
    executor.shutdown()


def test_a_goal_whose_answer_was_lost_is_adopted_not_sent_twice(ros_context, spin):
    """Under load the middleware dropped the server's answer to a goal it had taken ("failed to send
    response (timeout)"); send_goal used to send it again, so a second goal started and the caller's
    handle named one the server never ran (its result: STATUS_UNKNOWN). The goal it took is found on
    the action's status topic and its handle returned."""
    from rclpy.task import Future

    from seapup_common.ros.graph import send_goal
    server_node = rclpy.create_node("self_test_server", context=ros_context)
    client_node = rclpy.create_node("self_test_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(server_node)
    executor.add_node(client_node)
    ran = []

    async def counting(goal_handle):
        ran.append(bytes(goal_handle.goal_id.uuid))
        return await execute(goal_handle)
    ActionServer(server_node, SelfTest, "/seapup/self_test", execute_callback=counting)
    client = ActionClient(client_node, SelfTest, "/seapup/self_test")
    assert spin(executor, lambda: server_node.count_subscribers("/seapup/self_test/_action/feedback") > 0, 10.0)
    original = client.send_goal_async

    def answer_lost(goal, feedback_callback=None, goal_uuid=None):
        original(goal, feedback_callback=feedback_callback, goal_uuid=goal_uuid)
        return Future()   # the server gets it; its answer never reaches the caller
    client.send_goal_async = answer_lost
    feedback = []
    handle = send_goal(executor, client, SelfTest.Goal(operating_points=[0.5], step=0.14, sample_period=0.2),
                       lambda fb: feedback.append(fb.feedback), response_timeout=1.0, attempts=3)
    assert handle.accepted and ran == [bytes(handle.goal_id.uuid)]     # one goal, the one it ran
    result = handle.get_result_async()
    assert spin(executor, result.done, 10.0)
    assert result.result().status == 4 and result.result().result.message == "stepped by 0.14"
    assert len(ran) == 1
    executor.shutdown()


def test_a_service_answer_lost_is_asked_again_and_the_second_answer_returned(ros_context, spin):
    """The same lost answer on a service ("failed to send response (timeout)": the simulator set the thruster
    efficiency, the caller waited forever): call_idempotent asks again and returns the answer that came,
    leaving no request pending; a service that never answers is a clear error after its attempts."""
    import pytest
    from rclpy.task import Future
    from seapup_msgs.srv import SetThrusterEfficiency

    from seapup_common.ros.graph import ServiceNotAnswered, call_idempotent
    server_node = rclpy.create_node("simulator", context=ros_context)
    client_node = rclpy.create_node("caller", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(server_node)
    executor.add_node(client_node)
    heard = []

    def serve(request, response):
        heard.append(list(request.efficiency))
        response.success, response.message = True, f"request {len(heard)}"
        return response
    server_node.create_service(SetThrusterEfficiency, "/seapup/simulator/set_thruster_efficiency", serve)
    client = client_node.create_client(SetThrusterEfficiency, "/seapup/simulator/set_thruster_efficiency")
    original, calls = client.call_async, []

    def first_answer_lost(request):
        future = original(request)
        calls.append(future)
        return Future() if len(calls) == 1 else future   # the server does the first; its answer is lost
    client.call_async = first_answer_lost
    request = SetThrusterEfficiency.Request(efficiency=[0.0, 1.0, 1.0, 1.0])
    response = call_idempotent(executor, client, request, response_timeout=1.0, attempts=3)
    assert response.success and response.message == "request 2"
    assert heard == [[0.0, 1.0, 1.0, 1.0]] * 2 and len(calls) == 2
    assert spin(executor, calls[0].done, 2.0)   # the first answer came to its own future, not the caller's
    client.call_async = lambda request: Future()   # now nothing is ever answered
    with pytest.raises(ServiceNotAnswered, match="did not answer 2 requests"):
        call_idempotent(executor, client, request, response_timeout=0.3, attempts=2)
    assert not client._pending_requests
    executor.shutdown()
