"""Readiness rules (``readiness.py``) over real ``diagnostic_msgs`` messages and a stated reader count."""
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from seapup_bringup.graph import readiness

READERS = {"/seapup/navigation/odometry": 3, "/seapup/reference/position": 1}


def status(name, level=DiagnosticStatus.OK, message="ok", **subscribers):
    return DiagnosticStatus(name=name, level=level, message=message,
                            values=[KeyValue(key=f"subscribers:{topic}", value=str(n))
                                    for topic, n in subscribers.items()])


def array(t, *statuses):
    msg = DiagnosticArray(status=list(statuses))
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), round((t - int(t)) * 1e9)
    return msg


def count(topic):
    return READERS.get(topic, 0)


NAV = "/seapup/navigation/odometry"


def test_required_splits_the_ok_statuses_from_the_matched_only_ones():
    assert readiness.required(None) == ((), ())
    assert readiness.required("") == ((), readiness.MATCHED_ONLY)
    assert readiness.required(readiness.DEFAULT_READY) == (readiness.DEFAULT_READY, readiness.MATCHED_ONLY)


def test_the_newest_status_of_each_node_counts():
    diagnostics = [array(1.0, status("a", level=DiagnosticStatus.ERROR)), array(2.0, status("b")),
                   array(3.0, status("a"))]
    found = readiness.latest_statuses(diagnostics)
    assert found["a"].level == DiagnosticStatus.OK and set(found) == {"a", "b"}
    assert readiness.latest_statuses(diagnostics, window=1).keys() == {"a"}


def test_ready_needs_ok_and_every_reader_matched():
    navigator = status("seapup/navigator", level=DiagnosticStatus.WARN, **{NAV: 3})
    task = status("seapup/task_controller", **{"/seapup/reference/position": 1})
    found = {s.name: s for s in (navigator, task)}
    assert readiness.graph_ready(found, ["seapup/task_controller"], ["seapup/navigator"], count)
    # the navigator's estimate has reached 2 of the 3 readers the probe sees: not ready, whatever its level
    found["seapup/navigator"] = status("seapup/navigator", **{NAV: 2})
    assert not readiness.graph_ready(found, ["seapup/task_controller"], ["seapup/navigator"], count)
    # a status that must say OK and does not; a status never heard
    found = {"seapup/task_controller": status("seapup/task_controller", level=DiagnosticStatus.WARN)}
    assert not readiness.graph_ready(found, ["seapup/task_controller"], [], count)
    assert not readiness.graph_ready({}, [], ["seapup/navigator"], count)


def test_the_report_says_what_each_status_said():
    found = {"seapup/navigator": status("seapup/navigator", message="no fix", **{NAV: 2})}
    text = readiness.not_ready_report(found, ["seapup/navigator", "seapup/task_controller"], count)
    assert text == "seapup/navigator: 'no fix' (matched readers: [2] of [3]); seapup/task_controller: no status"


def test_handled_since_reads_the_status_stamp():
    diagnostics = [array(10.0, status("seapup/task_controller")), array(10.2, status("seapup/navigator"))]
    assert readiness.handled_since(diagnostics, "seapup/task_controller", 10.0)
    assert not readiness.handled_since(diagnostics, "seapup/task_controller", 10.2)


def test_stream_started_reads_the_stream_s_first_stamp_from_its_own_node():
    def said(name, start):
        return DiagnosticStatus(name=name, values=[KeyValue(key="setpoints", value="3"),
                                                   KeyValue(key="stream_start", value=str(start))])
    diagnostics = [array(10.0, said("seapup/task_controller", None)), array(10.0, said("seapup/navigator", 10.2))]
    assert not readiness.stream_started(diagnostics, "seapup/task_controller", 10.2)   # no stream yet
    diagnostics.append(array(10.0, said("seapup/task_controller", 10.2)))
    assert readiness.stream_started(diagnostics, "seapup/task_controller", 10.2)
    assert not readiness.stream_started(diagnostics, "seapup/task_controller", 10.4)  # an older stream's start
    assert not readiness.stream_started(diagnostics, "seapup/position_controller", 10.2)
