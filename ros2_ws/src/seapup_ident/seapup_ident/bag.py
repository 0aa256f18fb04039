"""rosbag2 bags in MCAP storage, written and read without rosbag2.

There is no rosbag2 on PyPI, so seapup writes and reads rosbag2 directories
(``metadata.yaml`` + ``<name>_0.mcap``, format version 9 as in Jazzy) with the
pure-Python ``rosbags`` library. Messages go in and come out as the CDR bytes
rclpy's raw subscriptions deliver, so nothing is decoded on the recording path.
The bags open in ``ros2 bag`` and Foxglove on a real ROS 2 install.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

__all__ = ["BagError", "BagMessage", "make_typestore", "BagRecorder", "read_bag"]

#: rosbag2 metadata version written by ROS 2 Jazzy.
BAG_VERSION = 9


class BagError(RuntimeError):
    """A bag that cannot be written or read as asked."""


@dataclass(frozen=True)
class BagMessage:
    """One recorded message: topic, type name, receive time [ns] and CDR bytes."""

    topic: str
    msgtype: str
    t_ns: int
    cdr: bytes


def make_typestore(msg_files: dict[str, str | Path] | None = None):
    """A ROS 2 Jazzy typestore extended with project message definitions.

    Parameters
    ----------
    msg_files : dict, optional
        Maps full type names (``seapup_msgs/msg/BladePitch``) to ``.msg`` files.
    """
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name, path in (msg_files or {}).items():
        types.update(get_types_from_msg(Path(path).read_text(), name))
    if types:
        store.register(types)
    return store


class BagRecorder:
    """Writes raw CDR messages into a new rosbag2/MCAP directory.

    Parameters
    ----------
    path : str or Path
        Bag directory to create; it must not exist.
    typestore : rosbags Typestore
        Knows every message type that will be recorded (:func:`make_typestore`).

    Examples
    --------
    >>> with BagRecorder(tmp / "bag", make_typestore()) as bag:  # doctest: +SKIP
    ...     bag.write("/chatter", "std_msgs/msg/String", 0, cdr_bytes)
    """

    def __init__(self, path: str | Path, typestore):
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f"bag {self.path} exists already; choose a new directory")
        self.typestore = typestore
        self._writer = Writer(self.path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
        self._connections: dict[str, object] = {}
        self.count = 0

    def open(self) -> "BagRecorder":
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer.open()
        return self

    def write(self, topic: str, msgtype: str, t_ns: int, cdr: bytes) -> None:
        """Append one message; the first message of a topic fixes its type."""
        conn = self._connections.get(topic)
        if conn is None:
            if msgtype not in self.typestore.fielddefs:
                raise BagError(f"type {msgtype} of {topic} is unknown to the typestore; "
                               "pass its .msg file to make_typestore")
            conn = self._writer.add_connection(topic, msgtype, typestore=self.typestore)
            self._connections[topic] = conn
        elif conn.msgtype != msgtype:
            raise BagError(f"{topic} was recorded as {conn.msgtype}, not {msgtype}")
        self._writer.write(conn, int(t_ns), bytes(cdr))
        self.count += 1

    def close(self) -> None:
        """Write the MCAP summary and metadata.yaml (idempotent)."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def __enter__(self) -> "BagRecorder":
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()


def read_bag(path: str | Path, topics: list[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a rosbag2 bag in time order, optionally only some topics."""
    path = Path(path)
    if not (path / "metadata.yaml").is_file():
        raise BagError(f"{path} is not a closed rosbag2 bag (no metadata.yaml)")
    with Reader(path) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        for conn, t_ns, raw in reader.messages(connections=conns):
            yield BagMessage(conn.topic, conn.msgtype, t_ns, bytes(raw))
