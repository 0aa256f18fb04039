"""No DDS traffic leaves loopback.

Fast DDS discovers peers by joining the SPDP multicast group 239.255.0.1 on
every interface it may use. With ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST it
joins none and talks unicast on 127.0.0.1 only (checked on this machine: with
SUBNET, /proc/net/igmp lists 239.255.0.1 on eth0 while a node runs). This test
runs a node the way every test does and reads the kernel's multicast table.
"""
import ipaddress
import socket
import struct
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor

IGMP = Path("/proc/net/igmp")
DDS_SPDP_GROUP = ipaddress.IPv4Address("239.255.0.1")


def multicast_groups_by_interface():
    """{interface: {IPv4 groups}} from /proc/net/igmp (groups are little-endian hex)."""
    groups, device = {}, None
    for line in IGMP.read_text().splitlines()[1:]:
        if not line.startswith("\t"):
            device = line.split()[1]
            groups.setdefault(device, set())
        else:
            raw = int(line.split()[0], 16)
            groups[device].add(ipaddress.IPv4Address(socket.inet_ntoa(struct.pack("<I", raw))))
    return groups


def test_nodes_join_no_dds_multicast_group_off_loopback(ros_context, node_process, spin):
    sim = node_process(package="seapup_sim", executable="simulator")
    node = rclpy.create_node("probe", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    assert spin(executor, lambda: ("simulator", "/seapup") in node.get_node_names_and_namespaces(), 15.0), \
        sim.log_text()
    offenders = {dev: g for dev, g in multicast_groups_by_interface().items()
                 if dev != "lo" and DDS_SPDP_GROUP in g}
    assert offenders == {}, f"DDS multicast joined off loopback: {offenders}"
    executor.shutdown()
    node.destroy_node()
