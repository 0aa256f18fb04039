"""The simulator node's messages: one sample's serialised messages and its diagnostics status.

:func:`sample_messages` turns :meth:`SimulatorCore.outputs <seapup_sim.simulator_core.SimulatorCore.outputs>`
into the (publisher, :class:`Packed`) pairs of one sample, the manifest last (``sensors/sample``: the stamp t_k and
the topics published for it -- the acoustic fix only at some samples); :func:`diagnostics_of` builds the
``/diagnostics`` array from the core's counters, the lockstep server's state and the graph's problems.
"""
from __future__ import annotations

from functools import partial

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from seapup_common import frames
from seapup_common.lockstep.server import STOPPED
from seapup_common.ros import messages as conv

__all__ = ["Packed", "sample_messages", "diagnostics", "diagnostics_of"]

NED, FRD = frames.FRAME_NED, frames.FRAME_FRD


class Packed:
    """One message of a sample, serialised when first asked for and kept: a topic nobody subscribes to costs
    no packing (the sample's numbers are a snapshot, :meth:`SimulatorCore.outputs
    <seapup_sim.simulator_core.SimulatorCore.outputs>`, so bytes packed later -- for a late joiner, when the
    held sample is said again -- are the bytes packed at once).

    Examples
    --------
    >>> calls = []
    >>> packed = Packed(lambda x: calls.append(x) or b"%d" % x, 7)
    >>> calls
    []
    >>> packed(), packed(), calls
    (b'7', b'7', [7])
    """

    __slots__ = ("_pack", "_bytes")

    def __init__(self, pack, *args, **kwargs):
        self._pack, self._bytes = partial(pack, *args, **kwargs), None

    def __call__(self) -> bytes:
        if self._bytes is None:
            self._bytes, self._pack = self._pack(), None
        return self._bytes


def sample_messages(encode, publishers, out: dict, t_ns: int, profile, cable=None) -> list:
    """The (publisher, :class:`Packed` message) pairs of the sample ``out`` stamped ``t_ns``, the manifest last
    (it lists every topic of the sample, whoever subscribes: what the sample holds).

    Parameters
    ----------
    encode : seapup_common.ros.sample_bytes.SampleEncoder
        Packs the messages of :mod:`seapup_common.ros.messages` into bytes.
    publishers : object
        Has ``pub_applied``, ``pub_velocity``, ... ``pub_manifest`` (``pub_tf`` None: no /tf).
    out : dict
        The core's outputs of the sample.
    t_ns : int
        Its stamp [ns].
    profile : seapup_sim.sensors.SensorProfile
        The sensors in force (the altimeter's field of view and range).
    cable : numpy.ndarray or None
        The umbilical's shape, drawn when there is one.
    """
    p = publishers
    sample, m = out["sample"], out["sample"].measurement
    messages = [
        (p.pub_applied, Packed(encode.applied, out["applied_blade_pitch"], t_ns)),
        (p.pub_velocity, Packed(encode.velocity, m.velocity, m.rates, t_ns)),
        (p.pub_imu, Packed(encode.imu, m.attitude, m.rates, sample.specific_force, t_ns)),
        *([(p.pub_position, Packed(encode.position, m.position, t_ns))] if m.position.valid else []),
        (p.pub_depth, Packed(encode.depth, m.depth, t_ns)),
        (p.pub_altitude, Packed(encode.altitude,  # every sample: +inf when invalid (REP-117)
                                m.altitude, t_ns, field_of_view=profile.altimeter_field_of_view,
                                min_range=profile.altimeter_min_range, max_range=profile.altimeter_max_range)),
        (p.pub_truth, Packed(encode.odometry_ned, sample.state, t_ns)),
        (p.pub_odom, Packed(encode.odometry_enu, sample.state, t_ns)),
        (p.pub_current, Packed(encode.vector3_stamped, sample.current_ned, t_ns, NED)),
        (p.pub_wrench, Packed(encode.wrench_stamped, sample.umbilical_body, t_ns, FRD)),
        *([(p.pub_tf, Packed(encode.transforms_enu, sample.state, t_ns))] if p.pub_tf is not None else [])]
    if cable is not None:   # a simulation with an umbilical: its shape, to be drawn
        messages.append((p.pub_cable, Packed(encode.path_ned, cable, t_ns)))
    # last: what this sample holds (the acoustic fix comes only at some samples)
    manifest = Packed(encode.manifest, [publisher.topic_name for publisher, _ in messages], t_ns)
    return messages + [(p.pub_manifest, manifest)]


def diagnostics(level: int, message: str, values: dict, t_ns: int) -> DiagnosticArray:
    """The simulator's ``/diagnostics`` array (stamped with the graph's time: the simulator owns it)."""
    status = DiagnosticStatus(level=level, name="seapup/simulator", hardware_id="seapup_sim",
                              message=message, values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])
    array = DiagnosticArray(status=[status])
    array.header.stamp = conv.ns_to_stamp(t_ns)
    return array


def diagnostics_of(mode: str, simulator, server, problems: list, samples_published: int,
                   elapsed: float) -> DiagnosticArray:
    """The simulator's status: ERROR when halted, WARN with graph problems, an active watchdog or a
    rejection, the hold it is in; counters and rates as values (``elapsed``: wall seconds since start)."""
    c = simulator.counters
    rejected = sum(v for k, v in c.items() if k.startswith("rejected"))
    level, message = DiagnosticStatus.OK, f"{mode}, t = {simulator.t:.1f} s"
    if server.halted:
        level, message = DiagnosticStatus.ERROR, message + f", halted: {server.halted}"
    elif problems:
        level, message = DiagnosticStatus.WARN, message + ", " + "; ".join(problems)
    elif simulator.watchdog_active:
        level, message = DiagnosticStatus.WARN, message + ", watchdog active (no valid command)"
    if server.user_hold is not None:
        message += ", stopped" if server.user_hold == STOPPED else ", paused"
    elif server.start_held and server.started:
        message += ", held at t_0 (start_held)"
    elif server.at_end:
        message += f", at end_time {server.end_ns * 1e-9:g} s (holding)"
    elif rejected:
        level, message = DiagnosticStatus.WARN, message + f", last rejection: {simulator.last_error}"
    values = {**c, "samples_published": samples_published, "sim_time": f"{simulator.t:.3f}",
              "real_time_factor_measured": f"{simulator.t / elapsed:.2f}" if elapsed > 0 else "0",
              "control_steps_per_wall_second": f"{c['steps'] / elapsed:.1f}" if elapsed > 0 else "0",
              "watchdog_active": str(simulator.watchdog_active), "at_end": str(server.at_end),
              "vehicle": simulator.config.vehicle, "sensor_profile": simulator.sensor_profile.name}
    return diagnostics(level, message, values, simulator.t_ns)
