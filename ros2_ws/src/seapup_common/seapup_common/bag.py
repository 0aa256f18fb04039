"""rosbag2 bags in MCAP storage, written, read, inspected and recovered without rosbag2.

There is no rosbag2 on PyPI, so seapup writes the rosbag2 Jazzy layout itself
with the ``mcap`` library's writer (``ros2`` profile) and reads it with
``rosbags``:

- a bag is a directory ``<name>/`` holding ``<name>_0.mcap`` (then
  ``<name>_1.mcap``, ... when it is split, as rosbag2 splits) and
  ``metadata.yaml`` (rosbag2 format version 9, ``ros_distro: jazzy``), with per
  topic the offered QoS profiles of its publishers and its RIHS01 type hash;
- every MCAP channel carries ``offered_qos_profiles`` (YAML) and
  ``topic_type_hash`` in its metadata, every schema the full ``ros2msg``
  definition, and the file ends with the ``rosbag2`` metadata record rosbag2's
  MCAP plugin writes;
- each message has a log time (when it was received) and a publish time (when
  it was sent), in the graph's time (sim time under ``/clock``);
- crash safety: :class:`BagWriter` closes the chunk in progress, flushes and
  fsyncs at least every ``flush_interval`` (wall or graph seconds, whichever
  comes first), so a killed recorder loses at most that; :func:`recover_bag`
  rebuilds a readable, indexed bag and its metadata.yaml from the complete
  chunks of what is on disk (``ros2 bag reindex`` does the metadata half).

Messages go in and come out as CDR bytes (rclpy raw subscriptions,
``rclpy.serialization``): nothing is decoded on the recording path.
"""
from __future__ import annotations

import fcntl
import io
import os
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import yaml
from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

__all__ = ["BagError", "BagMessage", "QosProfileDict", "make_typestore", "BagWriter", "header_stamp_ns", "read_bag", "bag_info", "writer_alive",
           "recover_bag", "storage_file", "storage_files", "DEFAULT_QOS", "BAG_VERSION"]

#: rosbag2 metadata version written by ROS 2 Jazzy.
BAG_VERSION = 9
ROS_DISTRO = "jazzy"
#: rosbag2 Jazzy's MCAP chunk size (its default storage configuration), bytes.
CHUNK_SIZE = 786_432
#: "infinite" duration as rosbag2 writes it (RMW_DURATION_INFINITE = INT64_MAX ns).
_INFINITE = {"sec": 9223372036, "nsec": 854775807}
_UNSPECIFIED = {"sec": 0, "nsec": 0}

QosProfileDict = dict
#: The profile rosbag2 writes for a reliable, volatile keep-last-10 publisher.
DEFAULT_QOS: QosProfileDict = {
    "history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile",
    "deadline": dict(_INFINITE), "lifespan": dict(_INFINITE), "liveliness": "automatic",
    "liveliness_lease_duration": dict(_INFINITE), "avoid_ros_namespace_conventions": False,
}


class BagError(RuntimeError):
    """A bag that cannot be written, read or recovered as asked."""


@dataclass(frozen=True)
class BagMessage:
    """One recorded message: topic, type, log (receive) time [ns], publish time [ns], CDR bytes."""

    topic: str
    msgtype: str
    t_ns: int
    cdr: bytes
    publish_ns: int = 0


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


def storage_file(bag_dir: str | Path, index: int = 0) -> Path:
    """The ``index``-th MCAP file of a bag directory, named as rosbag2 names it: ``<dir>/<dir>_<index>.mcap``."""
    bag_dir = Path(bag_dir)
    return bag_dir / f"{bag_dir.name}_{index}.mcap"


def storage_files(bag_dir: str | Path) -> list[Path]:
    """Every MCAP file of a bag in order: ``<dir>_0.mcap``, ``<dir>_1.mcap``, ... (as ``ros2 bag reindex`` finds them)."""
    bag_dir = Path(bag_dir)
    prefix = f"{bag_dir.name}_"
    found = []
    for f in bag_dir.glob(f"{prefix}*.mcap"):
        number = f.name[len(prefix):-len(".mcap")]
        if number.isdigit():
            found.append((int(number), f))
    return [f for _, f in sorted(found)]


def _qos_yaml(profiles: list[QosProfileDict]) -> str:
    return yaml.safe_dump(profiles, default_flow_style=False, sort_keys=False).strip() if profiles else ""


@dataclass
class _Topic:
    name: str
    msgtype: str
    channel_id: int
    type_hash: str
    qos: list = field(default_factory=list)
    count: int = 0


@dataclass
class _File:
    path: str
    start_ns: int | None = None
    end_ns: int = 0
    count: int = 0


def _metadata(topics: list[_Topic], files: list[_File]) -> dict:
    """The ``rosbag2_bagfile_information`` mapping rosbag2 Jazzy writes (version 9)."""
    count = sum(t.count for t in topics)
    starts = [f.start_ns for f in files if f.count]
    start = min(starts) if starts else 0
    duration = max(0, max(f.end_ns for f in files if f.count) - start) if starts else 0
    return {"rosbag2_bagfile_information": {
        "version": BAG_VERSION,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": count,
        "topics_with_message_count": [
            {"topic_metadata": {"name": t.name, "type": t.msgtype, "serialization_format": "cdr",
                                "offered_qos_profiles": t.qos, "type_description_hash": t.type_hash},
             "message_count": t.count} for t in topics],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [f.path for f in files],
        "files": [{"path": f.path, "starting_time": {"nanoseconds_since_epoch": f.start_ns if f.count else 0},
                   "duration": {"nanoseconds": max(0, f.end_ns - f.start_ns) if f.count else 0},
                   "message_count": f.count} for f in files],
        "custom_data": None,
        "ros_distro": ROS_DISTRO,
    }}


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class BagWriter:
    """Writes raw CDR messages into a new rosbag2 (v9, MCAP) bag directory.

    Parameters
    ----------
    path : str or Path
        Bag directory to create; it must not exist.
    typestore : rosbags Typestore
        Knows every message type that will be recorded (:func:`make_typestore`);
        gives the schema text and, when the graph does not tell, the type hash.
    flush_interval : float
        Close the chunk in progress, flush and fsync at least this often [s]
        of wall time or of message (graph) time, whichever comes first; a
        killed writer loses at most this much. 0 flushes after every message.
    chunk_size : int
        Largest chunk [bytes] (rosbag2 Jazzy's default).
    max_bag_size, max_bag_duration : float
        Start the next file ``<dir>_<N+1>.mcap`` once the current one holds
        this many bytes / seconds of log time, as rosbag2's splitting does
        (0: no limit).
    max_file_chunks : int
        Start the next file after this many chunks. Every chunk leaves an
        index entry (~1.4 kB) in memory until its file is finished, and a
        graph running far faster than real time closes a chunk every
        ``flush_interval`` of graph time, so this bounds the writer's memory
        however long and fast the recording.

    Examples
    --------
    >>> with BagWriter(tmp / "run", make_typestore()) as bag:  # doctest: +SKIP
    ...     bag.add_topic("/chatter", "std_msgs/msg/String")
    ...     bag.write("/chatter", cdr_bytes, log_time_ns=t, publish_time_ns=t)
    """

    def __init__(self, path: str | Path, typestore, *, flush_interval: float = 1.0,
                 chunk_size: int = CHUNK_SIZE, max_bag_size: float = 0, max_bag_duration: float = 0,
                 max_file_chunks: int = 4096):
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f"bag {self.path} exists already; choose a new directory")
        if not flush_interval >= 0:
            raise BagError(f"flush interval must be >= 0 s, got {flush_interval!r}")
        if not (max_bag_size >= 0 and max_bag_duration >= 0 and max_file_chunks >= 1):
            raise BagError("max_bag_size and max_bag_duration must be >= 0, max_file_chunks >= 1")
        self.typestore = typestore
        self.flush_interval = float(flush_interval)
        self.chunk_size = int(chunk_size)
        self.max_bag_size = float(max_bag_size)
        self.max_bag_duration_ns = int(max_bag_duration * 1e9)
        self.max_file_chunks = int(max_file_chunks)
        self.topics: dict[str, _Topic] = {}
        self.count = 0
        self.start_ns: int | None = None
        self.end_ns = 0
        self.files: list[_File] = []
        self._schemas: dict[str, int] = {}
        self._schema_records: dict[str, tuple[str, bytes]] = {}  # name: (encoding, data), for the next file
        self._channel_metadata: dict[str, dict] = {}
        self._file = None
        self._writer: Writer | None = None
        self._library = ""
        self._file_chunks = 0
        self._unflushed = 0
        self._last_flush_wall = 0.0
        self._last_flush_ns: int | None = None
        self._dir_fd: int | None = None

    # -- life cycle ------------------------------------------------------------------
    def open(self) -> "BagWriter":
        self.path.mkdir(parents=True)
        self._lock_directory()
        return self._start("seapup (rosbag2 jazzy layout, mcap writer)")

    def _lock_directory(self) -> None:
        """Hold an exclusive ``flock`` on the bag directory while writing: :func:`recover_bag` refuses a
        bag whose writer is alive (the kernel drops the lock when the writer ends, however it ends)."""
        self._dir_fd = os.open(self.path, os.O_RDONLY | os.O_DIRECTORY)
        try:
            fcntl.flock(self._dir_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self._dir_fd)
            self._dir_fd = None
            raise BagError(f"another process is writing {self.path}") from None

    @classmethod
    def into_existing(cls, path: str | Path, typestore) -> "BagWriter":
        """An open writer of ``<path>/<name>_0.mcap`` in an existing directory whose
        MCAP files were moved away (what :func:`recover_bag` rebuilds into)."""
        writer = cls.__new__(cls)
        cls.__init__(writer, Path(path).with_name(Path(path).name + ".new"), typestore, flush_interval=3600.0,
                     max_file_chunks=1 << 30)
        writer.path = Path(path)
        writer._lock_directory()
        return writer._start("seapup (rosbag2 jazzy layout, recovered)")

    def _start(self, library: str) -> "BagWriter":
        self._library = library
        target = storage_file(self.path, len(self.files))
        self._file = open(target, "xb")
        self._writer = Writer(self._file, chunk_size=self.chunk_size, compression=CompressionType.NONE)
        self._writer.start(profile="ros2", library=library)
        self.files.append(_File(target.name))
        self._file_chunks = 0
        self._last_flush_wall = time.monotonic()
        self._schemas = {}
        for name, (encoding, data) in self._schema_records.items():  # a new file declares them again
            self._schemas[name] = self._writer.register_schema(name, encoding, data)
        for entry in self.topics.values():
            entry.channel_id = self._writer.register_channel(entry.name, "cdr", self._schemas[entry.msgtype],
                                                             self._channel_metadata[entry.name])
        return self

    def _finish_file(self) -> None:
        """Summary, indexes and the ``rosbag2`` metadata record; flushed and fsync'd."""
        meta = self.metadata()
        self._writer.add_metadata("rosbag2", {
            "serialized_metadata": yaml.safe_dump(meta["rosbag2_bagfile_information"], sort_keys=False),
            "ROS_DISTRO": ROS_DISTRO})
        self._writer.finish()
        self._file.flush()
        os.fsync(self._file.fileno())
        self._file.close()
        self._writer = self._file = None

    def _split(self) -> None:
        """Finish the current file and continue in ``<dir>_<N+1>.mcap`` (metadata.yaml updated)."""
        self._finish_file()
        _write_metadata_file(self.path, self.metadata())
        self._start(self._library)

    def add_recorded_channel(self, channel: Channel, schema: Schema) -> None:
        """Re-declare a channel read back from a bag (its schema and metadata as they were)."""
        if channel.topic in self.topics:
            return
        self._declare(channel.topic, schema.name, schema.encoding, schema.data, dict(channel.metadata),
                      channel.metadata.get("topic_type_hash", ""),
                      _parse_qos(channel.metadata.get("offered_qos_profiles", "")))

    def _declare(self, topic, msgtype, encoding, schema_data, metadata, type_hash, qos) -> None:
        if msgtype not in self._schemas:
            self._schema_records[msgtype] = (encoding, schema_data)
            self._schemas[msgtype] = self._writer.register_schema(msgtype, encoding, schema_data)
        self._channel_metadata[topic] = metadata
        cid = self._writer.register_channel(topic, "cdr", self._schemas[msgtype], metadata)
        self.topics[topic] = _Topic(topic, msgtype, cid, type_hash, qos)

    def close(self) -> None:
        """Finish the MCAP file (summary, indexes, the ``rosbag2`` metadata record) and
        write metadata.yaml; both fsync'd (idempotent)."""
        if self._writer is None:
            return
        self._finish_file()
        _write_metadata_file(self.path, self.metadata())
        if self._dir_fd is not None:
            os.close(self._dir_fd)  # the lock goes with it
            self._dir_fd = None

    def __enter__(self) -> "BagWriter":
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    # -- topics and messages ------------------------------------------------------------
    def add_topic(self, topic: str, msgtype: str, *, qos: list[QosProfileDict] | None = None,
                  type_hash: str = "") -> None:
        """Declare a topic before its first message.

        ``qos`` are the offered profiles of its publishers (rosbag2 keys;
        default: one reliable, volatile keep-last-10 profile); ``type_hash``
        the RIHS01 hash the graph reports (default: computed from the type).
        """
        if self._writer is None:
            raise BagError("open the bag before adding topics")
        if topic in self.topics:
            if self.topics[topic].msgtype != msgtype:
                raise BagError(f"{topic} was recorded as {self.topics[topic].msgtype}, not {msgtype}")
            return
        if msgtype not in self.typestore.fielddefs:
            raise BagError(f"type {msgtype} of {topic} is unknown to the typestore; "
                           "pass its .msg file to make_typestore")
        text, _ = self.typestore.generate_msgdef(msgtype, ros_version=2)
        qos = [dict(DEFAULT_QOS)] if qos is None else [dict(q) for q in qos]
        type_hash = type_hash or self.typestore.hash_rihs01(msgtype)
        self._declare(topic, msgtype, "ros2msg", text.encode(),
                      {"offered_qos_profiles": _qos_yaml(qos), "topic_type_hash": type_hash}, type_hash, qos)

    def write(self, topic: str, cdr: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Append one message of a declared topic, then flush if the interval has passed."""
        entry = self.topics.get(topic)
        if entry is None:
            raise BagError(f"topic {topic} was not added to the bag")
        log_time_ns = int(log_time_ns)
        publish_time_ns = log_time_ns if publish_time_ns is None else int(publish_time_ns)
        current = self.files[-1]
        if current.count and self._split_due(current, log_time_ns):
            self._split()
            entry, current = self.topics[topic], self.files[-1]
        self._writer.add_message(entry.channel_id, log_time=log_time_ns, data=bytes(cdr),
                                 publish_time=publish_time_ns, sequence=entry.count)
        entry.count += 1
        self.count += 1
        self._unflushed += 1
        current.count += 1
        current.start_ns = log_time_ns if current.start_ns is None else min(current.start_ns, log_time_ns)
        current.end_ns = max(current.end_ns, log_time_ns)
        self.start_ns = log_time_ns if self.start_ns is None else min(self.start_ns, log_time_ns)
        self.end_ns = max(self.end_ns, log_time_ns)
        self._maybe_flush(log_time_ns)

    def _split_due(self, current: _File, log_time_ns: int) -> bool:
        return (self._file_chunks >= self.max_file_chunks
                or (self.max_bag_size > 0 and self._file.tell() >= self.max_bag_size)
                or (self.max_bag_duration_ns > 0 and log_time_ns - current.start_ns >= self.max_bag_duration_ns))

    def _maybe_flush(self, t_ns: int) -> None:
        now = time.monotonic()
        if self._last_flush_ns is None:
            self._last_flush_ns = t_ns
        if (now - self._last_flush_wall >= self.flush_interval
                or (t_ns - self._last_flush_ns) * 1e-9 >= self.flush_interval):
            self.flush()
            self._last_flush_wall, self._last_flush_ns = now, t_ns

    def flush(self) -> None:
        """Close the chunk in progress and make everything so far durable (flush + fsync)."""
        if self._writer is not None:
            self._writer.flush()
            os.fsync(self._file.fileno())
            if self._unflushed:
                self._file_chunks += 1
                self._unflushed = 0

    def metadata(self) -> dict:
        """The metadata.yaml content for what has been written so far."""
        return _metadata(list(self.topics.values()), self.files)


def _write_metadata_file(bag_dir: Path, meta: dict) -> None:
    path = bag_dir / "metadata.yaml"
    tmp = path.with_suffix(".yaml.tmp")
    tmp.write_text(yaml.safe_dump(meta, sort_keys=False))
    _fsync(tmp)
    tmp.replace(path)


def header_stamp_ns(cdr: bytes) -> int | None:
    """The header stamp [ns] of a CDR message whose first field is std_msgs/Header (None if it cannot be).

    Reads the 4-byte encapsulation header (bit 0 of byte 1: little endian),
    then ``builtin_interfaces/Time`` (int32 sec, uint32 nanosec) without
    decoding the rest.
    """
    if len(cdr) < 12:
        return None
    order = "<" if cdr[1] & 1 else ">"
    sec, nanosec = struct.unpack(order + "iI", cdr[4:12])
    return sec * 1_000_000_000 + nanosec if nanosec < 1_000_000_000 else None


def read_bag(path: str | Path, topics: list[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a closed rosbag2 bag in log-time order, optionally only some topics."""
    path = Path(path)
    if not (path / "metadata.yaml").is_file():
        raise BagError(f"{path} is not a closed rosbag2 bag (no metadata.yaml); "
                       "if its recorder was killed, run ./seapup bag recover on it")
    with Reader(path) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        for conn, t_ns, raw in reader.messages(connections=conns):
            yield BagMessage(conn.topic, conn.msgtype, t_ns, bytes(raw))


def read_bag_with_publish_times(path: str | Path, topics: list[str] | None = None) -> Iterator[BagMessage]:
    """Like :func:`read_bag`, with each message's publish time (read with the mcap library), file by file."""
    from mcap.reader import make_reader
    for storage in storage_files(path):
        with open(storage, "rb") as f:
            for schema, channel, message in make_reader(f).iter_messages(topics=topics, log_time_order=True):
                yield BagMessage(channel.topic, schema.name, message.log_time, bytes(message.data),
                                 message.publish_time)


def bag_info(path: str | Path) -> dict:
    """What ``ros2 bag info`` shows: files, size, duration, start/end, counts, types, QoS."""
    path = Path(path)
    meta_file = path / "metadata.yaml"
    if not meta_file.is_file():
        raise BagError(f"{path} has no metadata.yaml: not a closed bag (try ./seapup bag recover {path})")
    info = yaml.safe_load(meta_file.read_text())["rosbag2_bagfile_information"]
    files = [path / f for f in info["relative_file_paths"]]
    start = info["starting_time"]["nanoseconds_since_epoch"]
    return {"path": str(path), "files": [f.name for f in files], "bag_size_bytes": sum(f.stat().st_size for f in files),
            "storage_id": info["storage_identifier"], "ros_distro": info.get("ros_distro"),
            "duration_s": info["duration"]["nanoseconds"] * 1e-9, "start_s": start * 1e-9,
            "end_s": (start + info["duration"]["nanoseconds"]) * 1e-9, "messages": info["message_count"],
            "topics": [{"name": t["topic_metadata"]["name"], "type": t["topic_metadata"]["type"],
                        "count": t["message_count"],
                        "serialization_format": t["topic_metadata"]["serialization_format"],
                        "qos": t["topic_metadata"]["offered_qos_profiles"],
                        "type_hash": t["topic_metadata"].get("type_description_hash", "")}
                       for t in info["topics_with_message_count"]]}


def _parse_qos(text: str) -> list:
    try:
        value = yaml.safe_load(text) if text else []
    except yaml.YAMLError:
        return []
    return value if isinstance(value, list) else []


def writer_alive(path: str | Path) -> bool:
    """True while a :class:`BagWriter` (in any process) holds the bag directory's lock."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)  # closing drops a lock taken here
    return False


def recover_bag(path: str | Path, typestore=None) -> dict:
    """Rebuild a readable, indexed bag and its metadata.yaml from what is on disk.

    Reads each MCAP file of the bag (``<dir>_0.mcap``, ``<dir>_1.mcap``, ...)
    record by record up to the first incomplete or damaged one (the tail a
    killed writer left), keeps every message of the complete chunks, moves the
    files read to ``<file>.damaged`` (the damaged ones) or ``<file>.orig`` and
    writes one finished file and metadata.yaml in their place.

    Returns
    -------
    dict
        ``messages`` kept, ``topics``, ``stopped_at`` (why reading of the
        damaged file ended) and ``damaged_file``.

    Raises
    ------
    BagError
        If there is no MCAP file or not even the first one's header is readable.
    """
    path = Path(path)
    if writer_alive(path):
        raise BagError(f"{path} is still being written by a live recorder: stop it (Ctrl-C) and it "
                       "finishes the bag itself; recover only a bag whose writer died")
    sources = storage_files(path)
    if not sources:
        raise BagError(f"no {storage_file(path).name} in {path}: nothing to recover")
    schemas: dict[str, Schema] = {}
    channels: dict[str, Channel] = {}
    messages: list[tuple[str, Message]] = []
    stopped, damaged_name = "end of file", ""
    for source in sources:
        data = source.read_bytes()
        ids_schema: dict[int, Schema] = {}
        ids_topic: dict[int, str] = {}
        error = ""
        try:
            for record in StreamReader(io.BytesIO(data), skip_magic=False, emit_chunks=False).records:
                if isinstance(record, Schema):
                    ids_schema[record.id] = record
                elif isinstance(record, Channel):
                    ids_topic[record.id] = record.topic
                    if record.schema_id in ids_schema:
                        schemas.setdefault(record.topic, ids_schema[record.schema_id])
                        channels.setdefault(record.topic, record)
                elif isinstance(record, Message) and record.channel_id in ids_topic:
                    messages.append((ids_topic[record.channel_id], record))
        except (McapError, EOFError, ValueError, KeyError, IndexError, struct.error) as exc:
            error = f"{type(exc).__name__}: {exc}"[:200]
        if error and source == sources[0] and not ids_topic and len(data) < 8:
            raise BagError(f"{source} has no readable MCAP header ({error})")
        moved = source.with_name(source.name + (".damaged" if error else ".orig"))
        source.replace(moved)
        if error and not damaged_name:
            stopped, damaged_name = error, moved.name
    (path / "metadata.yaml").unlink(missing_ok=True)
    writer = BagWriter.into_existing(path, typestore or make_typestore())
    for topic, channel in channels.items():
        writer.add_recorded_channel(channel, schemas[topic])
    for topic, m in sorted(messages, key=lambda tm: tm[1].log_time):
        if topic in writer.topics:  # a channel whose schema was lost cannot be written back
            writer.write(topic, m.data, m.log_time, m.publish_time)
    writer.close()
    return {"messages": writer.count, "topics": {t: e.count for t, e in writer.topics.items()},
            "stopped_at": stopped, "damaged_file": damaged_name}
