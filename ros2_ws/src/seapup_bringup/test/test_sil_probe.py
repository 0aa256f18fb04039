"""The probe's logs as arrays (``sil_probe.py``): real messages in, SI arrays out, a sample said again once."""
import math

import numpy as np

from seapup_bringup.graph.sil_probe import TOPICS, import_path, log_arrays, once_per_stamp


def message(name, t):
    msg = import_path(TOPICS[name][1])()
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), round((t - int(t)) * 1e9)
    return msg


def odometry(name, t, x, yaw):
    msg = message(name, t)
    msg.pose.pose.position.x = x
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return msg


def test_a_sample_said_again_is_kept_once_the_last_copy():
    a, b, again, c = (odometry("truth", t, x, 0.0) for t, x in ((0.0, 1.0), (0.2, 2.0), (0.2, 3.0), (0.4, 4.0)))
    assert once_per_stamp([a, b, again, c]) == [a, again, c]


def test_arrays_in_si_units_with_one_row_per_sample():
    log = {name: [] for name in TOPICS}
    log["truth"] = [odometry("truth", 0.0, 1.0, 0.0), odometry("truth", 0.2, 2.0, math.pi / 2),
                    odometry("truth", 0.2, 2.0, math.pi / 2)]       # the simulator said 0.2 s again
    near, far = message("altitude", 0.2), message("altitude", 0.4)
    for msg, reading in ((near, 3.0), (far, 80.0)):
        msg.min_range, msg.max_range, msg.range = 0.3, 50.0, reading
    log["altitude"] = [near, far]
    out = log_arrays(log)
    assert np.array_equal(out["truth_t"], [0.0, 0.2])
    assert np.allclose(out["truth_position"][:, 0], [1.0, 2.0])
    assert np.allclose(out["truth_attitude"][1], [0.0, 0.0, math.pi / 2])   # yaw 90 deg, from the quaternion
    assert out["estimate_position"].shape == (0, 3) and out["command"].shape == (0, 4)
    assert out["altitude"][0] == 3.0 and math.isnan(out["altitude"][1])  # out of range: no reading


def test_a_harness_wait_its_bound_ended_is_named_among_the_ended_waits(tmp_path):
    """The SIL harness resumes a held graph once it heard what it waits for; a wait whose wall-clock bound ran out
    first is counted and named by ``SilGraph.ended_waits`` beside the nodes' own (the run may be the machine's)."""
    from types import SimpleNamespace

    from seapup_bringup.graph import sil as sil_module
    calls = []

    def spin_until(predicate, wait):
        calls.append(wait)
        return predicate()
    fake = SimpleNamespace(spin_until=spin_until)
    sil_module._harness_wait(fake, lambda: True, "heard")
    assert not hasattr(fake, "harness_waits_ended") and calls == [sil_module.HARNESS_WAIT]
    sil_module._harness_wait(fake, lambda: False, "setpoint")
    sil_module._harness_wait(fake, lambda: False, "setpoint")
    assert fake.harness_waits_ended == {"setpoint": 2}
    graph = sil_module.SilGraph(out_dir=tmp_path)    # not started: no process, no ROS
    assert graph.ended_waits() == {}
    graph.harness_waits_ended = {"setpoint": 2}
    assert graph.ended_waits() == {"harness": {"setpoint": 2}}
