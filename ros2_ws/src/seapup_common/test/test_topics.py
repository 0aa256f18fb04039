"""The topic table (seapup_common.topics): one name per topic, each with a message type that exists."""
import pytest

from seapup_common import topics
from seapup_common.ros.introspection import interface_class

#: The names of topics among the module's public constants (the rest are the namespace, services, actions and
#: the type of a family of topics named by a function).
TOPIC_NAMES = [n for n in topics.__all__ if n.isupper() and isinstance(getattr(topics, n), str)
               and n != "NAMESPACE" and not n.endswith(("_SERVICE", "_ACTION", "_TYPE"))]


def test_every_named_topic_is_in_the_table_once_and_nothing_else_is():
    values = [getattr(topics, n) for n in TOPIC_NAMES]
    assert len(set(values)) == len(values)
    assert set(values) == set(topics.TOPIC_TYPES)
    assert set(topics.SENSORS) <= set(values)


@pytest.mark.parametrize("name", TOPIC_NAMES)
def test_names_are_absolute_and_the_vehicle_s_are_in_its_namespace(name):
    topic = getattr(topics, name)
    assert topic.startswith("/") and not topic.endswith("/")
    # the graph-wide topics ROS tools look for at the root (tf2 listens on /tf and /tf_static)
    assert topic in (topics.CLOCK, topics.DIAGNOSTICS, topics.TF, topics.TF_STATIC) \
        or topic.startswith(topics.NAMESPACE + "/")


@pytest.mark.parametrize("topic", sorted(topics.TOPIC_TYPES))
def test_every_type_is_an_installed_message(topic):
    assert interface_class(topics.TOPIC_TYPES[topic]).__name__ == topics.TOPIC_TYPES[topic].rsplit("/", 1)[1]


def test_services_and_actions_are_in_the_namespace():
    for name in ("SELF_TEST_ACTION", "SET_CURRENT_SERVICE", "SWITCH_CONTROLLER_SERVICE"):
        assert getattr(topics, name).startswith(topics.NAMESPACE + "/")
    assert topics.task_action("hover") == "/seapup/task/hover"


def test_typed_refuses_a_topic_without_a_type():
    with pytest.raises(KeyError, match="/seapup/nowhere"):
        topics.typed(topics.COMMAND, "/seapup/nowhere")


def test_a_controller_s_estimate_topic_is_in_its_node_s_namespace_with_an_installed_type():
    assert topics.controller_estimate("explicit") == topics.NAMESPACE + "/explicit/estimate"
    assert interface_class(topics.CONTROLLER_ESTIMATE_TYPE).__name__ == "ControllerEstimate"
