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
import mmap
import os
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import yaml
from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, Footer, Message, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

__all__ = ["BagError", "BagMessage", "QosProfileDict", "make_typestore", "BagWriter", "header_stamp_ns", "read_bag", "bag_info", "writer_alive",
           "recover_bag", "storage_file", "storage_files", "DEFAULT_QOS", "BAG_VERSION", "read_metadata",
           "check_storage_files", "MCAP_MAGIC"]

#: The eight bytes an MCAP file starts and ends with.
MCAP_MAGIC = b"\x89MCAP0\r\n"
#: The most files a bag's metadata.yaml may list (a split bag of 10 000 files is far beyond any seapup run).
MAX_BAG_FILES = 10_000
#: The most topics a bag's metadata.yaml may list.
MAX_BAG_TOPICS = 100_000
#: The largest uncompressed chunk :func:`recover_bag` decompresses (rosbag2 writes 0.75 MiB chunks).
MAX_CHUNK_BYTES = 256 << 20
_INT64_MAX = (1 << 63) - 1

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


def _require(condition: bool, source, what: str, value) -> None:
    if not condition:
        shown = repr(value)
        raise BagError(f"{source}: {what}, got {shown[:80]}{'...' if len(shown) > 80 else ''}")


def _count(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= _INT64_MAX


def read_metadata(path: str | Path) -> dict:
    """The ``rosbag2_bagfile_information`` of a bag's metadata.yaml, read bounded and strictly
    (:mod:`seapup_common.input_files`, kind ``bag_metadata``) and checked: the fields seapup uses have their
    types and ranges (counts and times integers in [0, 2^63)), and every file it lists is a plain file name
    present in the bag directory.

    Raises
    ------
    BagError
        One line naming the bag, the field and what is wrong (a missing metadata.yaml says to recover the bag).
    """
    from seapup_common.input_files import InputFileError, load_yaml_file
    path = Path(path)
    if not path.is_dir():
        raise BagError(f"{path}: no such bag directory")
    meta_file = path / "metadata.yaml"
    if not meta_file.exists() and not storage_files(path):
        raise BagError(f"{path} is not a bag: it has neither metadata.yaml nor {storage_file(path).name}")
    if not meta_file.exists():
        raise BagError(f"{path} has no metadata.yaml: not a closed bag (if its recorder was killed, run "
                       f"./seapup bag recover {path})")
    try:
        document = load_yaml_file(meta_file, "bag_metadata")
    except InputFileError as exc:
        raise BagError(str(exc)) from None
    _require(isinstance(document, dict) and isinstance(document.get("rosbag2_bagfile_information"), dict),
             meta_file, "must be a mapping 'rosbag2_bagfile_information'", type(document).__name__)
    info = document["rosbag2_bagfile_information"]
    files = info.get("relative_file_paths")
    _require(isinstance(files, list) and 1 <= len(files) <= MAX_BAG_FILES, meta_file,
             f"relative_file_paths must be a list of 1 to {MAX_BAG_FILES} file names",
             files if not isinstance(files, list) else f"{len(files)} entries")
    for name in files:
        _require(isinstance(name, str) and name not in ("", ".", "..") and "/" not in name and "\0" not in name,
                 meta_file, "relative_file_paths: each entry must be a file name in the bag directory", name)
        if not (path / name).is_file():
            raise BagError(f"{meta_file} lists {name}, which is not in the bag (if the recorder was killed, run "
                           f"./seapup bag recover {path})")
    _require(_count(info.get("message_count")), meta_file, "message_count must be an integer in [0, 2^63)",
             info.get("message_count"))
    for key, field_name in (("duration", "nanoseconds"), ("starting_time", "nanoseconds_since_epoch")):
        value = info.get(key)
        _require(isinstance(value, dict) and _count(value.get(field_name)), meta_file,
                 f"{key}.{field_name} must be an integer in [0, 2^63)",
                 value.get(field_name) if isinstance(value, dict) else value)
    _require(isinstance(info.get("storage_identifier"), str), meta_file, "storage_identifier must be a string",
             info.get("storage_identifier"))
    topics = info.get("topics_with_message_count")
    _require(isinstance(topics, list) and len(topics) <= MAX_BAG_TOPICS, meta_file,
             f"topics_with_message_count must be a list of at most {MAX_BAG_TOPICS} topics",
             topics if not isinstance(topics, list) else f"{len(topics)} entries")
    for t in topics:
        meta = t.get("topic_metadata") if isinstance(t, dict) else None
        _require(isinstance(meta, dict) and all(isinstance(meta.get(k), str) for k in ("name", "type",
                                                                                      "serialization_format"))
                 and isinstance(meta.get("offered_qos_profiles", []), (list, str)) and _count(t.get("message_count")),
                 meta_file, "each of topics_with_message_count needs topic_metadata (name, type, "
                 "serialization_format: strings) and message_count (an integer >= 0)", t)
    return info


def _reading_problem(exc: Exception, source: Path, offset: int, size: int) -> str:
    """A reason, in words, why reading an MCAP file stopped (never an exception's name)."""
    from mcap.exceptions import EndOfFile, InvalidMagic, RecordLengthLimitExceeded
    if isinstance(exc, (EndOfFile, EOFError, struct.error)) or offset >= size:
        return f"{source.name} ends early (truncated at byte {size})"
    if isinstance(exc, InvalidMagic):
        return f"{source.name} has no MCAP end marker at byte {offset} (damaged or truncated)"
    if isinstance(exc, RecordLengthLimitExceeded):
        return f"{source.name} has a record at byte {offset} longer than the file (damaged)"
    text = str(exc).splitlines()[0][:120] if str(exc) else "unreadable"
    return f"{source.name} has a damaged record at byte {offset} ({text})"


def _magic_problem(source: Path) -> str:
    """Why ``source`` is not an MCAP file at all ('' if it starts with the MCAP magic bytes)."""
    try:
        with open(source, "rb") as f:
            head = f.read(len(MCAP_MAGIC))
    except OSError as exc:
        return f"{source} cannot be read ({exc.strerror or exc})"
    if not head:
        return f"{source} is empty: not an MCAP file, so not a bag"
    if head != MCAP_MAGIC:
        return f"{source} is not an MCAP file (it does not start with the MCAP magic bytes), so not a bag"
    return ""


def check_storage_files(path: str | Path) -> list[Path]:
    """The bag's MCAP files, each checked to start as an MCAP file and end with its summary (footer and
    end marker): what a reader needs before it seeks to the summary.

    Raises
    ------
    BagError
        For a bag without MCAP files, a file that is not MCAP (random bytes, empty), or one that ends early
        (a killed recorder's), naming the file, the byte and what to do.
    """
    path = Path(path)
    if not path.is_dir():
        raise BagError(f"{path}: no such bag directory")
    files = storage_files(path)
    if not files:
        raise BagError(f"{path} has no {storage_file(path).name}: not a bag")
    for source in files:
        problem = _magic_problem(source)
        if problem:
            raise BagError(problem)
        size = source.stat().st_size
        with open(source, "rb") as f:
            f.seek(max(size - len(MCAP_MAGIC), 0))
            tail = f.read(len(MCAP_MAGIC))
        if size < 2 * len(MCAP_MAGIC) or tail != MCAP_MAGIC:
            raise BagError(f"the bag's MCAP file {source.name} ends early (truncated at byte {size}): "
                           f"run ./seapup bag recover {path}")
    return files


def read_bag(path: str | Path, topics: list[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a closed rosbag2 bag in log-time order, optionally only some topics.

    The metadata (:func:`read_metadata`) and the MCAP files (:func:`check_storage_files`) are checked first;
    a reading error is a :class:`BagError` with a reason, never a reader's exception."""
    path = Path(path)
    read_metadata(path)
    check_storage_files(path)
    from rosbags.rosbag2 import ReaderError
    try:
        with Reader(path) as reader:
            conns = [c for c in reader.connections if topics is None or c.topic in topics]
            for conn, t_ns, raw in reader.messages(connections=conns):
                yield BagMessage(conn.topic, conn.msgtype, t_ns, bytes(raw))
    except (ReaderError, McapError, EOFError, struct.error, ValueError, KeyError) as exc:
        raise BagError(f"{path}: the bag cannot be read ({str(exc).splitlines()[0][:160] or 'damaged'}): "
                       f"run ./seapup bag recover {path}") from None


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
    info = read_metadata(path)
    files = [path / f for f in info["relative_file_paths"]]
    start = info["starting_time"]["nanoseconds_since_epoch"]
    return {"path": str(path), "files": [f.name for f in files], "bag_size_bytes": sum(f.stat().st_size for f in files),
            "storage_id": info["storage_identifier"], "ros_distro": info.get("ros_distro"),
            "duration_s": info["duration"]["nanoseconds"] * 1e-9, "start_s": start * 1e-9,
            "end_s": (start + info["duration"]["nanoseconds"]) * 1e-9, "messages": info["message_count"],
            "topics": [{"name": t["topic_metadata"]["name"], "type": t["topic_metadata"]["type"],
                        "count": t["message_count"],
                        "serialization_format": t["topic_metadata"]["serialization_format"],
                        "qos": _qos_list(t["topic_metadata"].get("offered_qos_profiles", [])),
                        "type_hash": t["topic_metadata"].get("type_description_hash", "")}
                       for t in info["topics_with_message_count"]]}


def _qos_list(value) -> list:
    """Offered QoS profiles as a list of mappings (metadata before version 9 holds them as YAML text)."""
    profiles = _parse_qos(value) if isinstance(value, str) else value
    return [p for p in profiles if isinstance(p, dict)] if isinstance(profiles, list) else []


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


@dataclass
class _Scan:
    """What reading one MCAP file record by record found."""

    source: Path
    problem: str = ""          # why reading stopped early ('' : the file read to its end marker)
    schemas: dict = field(default_factory=dict)     # topic -> Schema
    channels: dict = field(default_factory=dict)    # topic -> Channel
    messages: list = field(default_factory=list)    # (topic, Message)


def _scan(source: Path) -> _Scan:
    """Read ``source`` record by record up to its end marker or the first incomplete or damaged record.

    The file is memory-mapped (nothing is read into memory beyond what the records hold), no record may be
    longer than the file, and no chunk may claim more than :data:`MAX_CHUNK_BYTES` uncompressed."""
    scan = _Scan(source)
    size = source.stat().st_size
    ids_schema: dict[int, Schema] = {}
    ids_topic: dict[int, str] = {}
    with open(source, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
        reader = StreamReader(data, skip_magic=False, emit_chunks=True, record_size_limit=size)
        try:
            for outer in reader.records:
                if isinstance(outer, Chunk):
                    if outer.uncompressed_size > MAX_CHUNK_BYTES:
                        raise McapError(f"a chunk claims {outer.uncompressed_size} bytes uncompressed, more than "
                                        f"{MAX_CHUNK_BYTES}")
                    inner = breakup_chunk(outer, validate_crc=True)
                else:
                    inner = [outer]
                for record in inner:
                    if isinstance(record, Schema):
                        ids_schema[record.id] = record
                    elif isinstance(record, Channel):
                        ids_topic[record.id] = record.topic
                        if record.schema_id in ids_schema:
                            scan.schemas.setdefault(record.topic, ids_schema[record.schema_id])
                            scan.channels.setdefault(record.topic, record)
                    elif isinstance(record, Message) and record.channel_id in ids_topic:
                        scan.messages.append((ids_topic[record.channel_id], record))
        except Exception as exc:  # noqa: BLE001 - any reading error of a damaged file ends the scan with a reason
            scan.problem = _reading_problem(exc, source, data.tell(), size)
    return scan


def _metadata_problem(path: Path, count: int) -> str:
    """Why the bag's metadata.yaml needs rebuilding ('' if it is readable and counts ``count`` messages)."""
    try:
        info = read_metadata(path)
    except BagError as exc:
        return str(exc)
    if info["message_count"] != count:
        return f"metadata.yaml counts {info['message_count']} messages, the files hold {count}"
    return ""


def recover_bag(path: str | Path, typestore=None) -> dict:
    """Rebuild a readable, indexed bag and its metadata.yaml from what is on disk.

    Reads each MCAP file of the bag (``<dir>_0.mcap``, ``<dir>_1.mcap``, ...)
    record by record up to the first incomplete or damaged one (the tail a
    killed writer left), keeps every message of the complete chunks, moves the
    files read to ``<file>.damaged`` (the damaged ones) or ``<file>.orig`` and
    writes one finished file and metadata.yaml in their place. A bag whose files
    all read to their end and whose metadata.yaml agrees is intact: nothing is
    changed on disk.

    Returns
    -------
    dict
        ``intact`` (True: nothing was done), ``messages`` kept, ``topics``, ``stopped_at`` (why reading of
        the damaged file ended, '' if none was), ``damaged_file`` (the name it is kept under, '' if none)
        and ``kept`` (every original file's new name).

    Raises
    ------
    BagError
        If a writer is alive, there is no MCAP file, or a file is not MCAP at all (random bytes, empty): then
        nothing is changed on disk.
    """
    path = Path(path)
    if not path.is_dir():
        raise BagError(f"{path}: no such bag directory")
    if writer_alive(path):
        raise BagError(f"{path} is still being written by a live recorder: stop it (Ctrl-C) and it "
                       "finishes the bag itself; recover only a bag whose writer died")
    sources = storage_files(path)
    if not sources:
        raise BagError(f"{path} has no {storage_file(path).name}: not a bag, nothing to recover")
    for source in sources:   # before anything is moved: a file that is not MCAP is not ours to rewrite
        problem = _magic_problem(source)
        if problem:
            raise BagError(problem)
    scans = [_scan(source) for source in sources]
    total = sum(len(scan.messages) for scan in scans)
    damaged = [scan for scan in scans if scan.problem]
    if not damaged and not _metadata_problem(path, total):
        return {"intact": True, "messages": total, "topics": {}, "stopped_at": "", "damaged_file": "", "kept": []}
    schemas: dict[str, Schema] = {}
    channels: dict[str, Channel] = {}
    kept = []
    for scan in scans:
        for topic, channel in scan.channels.items():
            schemas.setdefault(topic, scan.schemas[topic])
            channels.setdefault(topic, channel)
        moved = scan.source.with_name(scan.source.name + (".damaged" if scan.problem else ".orig"))
        scan.source.replace(moved)
        kept.append(moved.name)
    (path / "metadata.yaml").unlink(missing_ok=True)
    writer = BagWriter.into_existing(path, typestore or make_typestore())
    for topic, channel in channels.items():
        writer.add_recorded_channel(channel, schemas[topic])
    messages = [tm for scan in scans for tm in scan.messages]
    for topic, m in sorted(messages, key=lambda tm: tm[1].log_time):
        if topic in writer.topics:  # a channel whose schema was lost cannot be written back
            writer.write(topic, m.data, m.log_time, m.publish_time)
    writer.close()
    first = damaged[0] if damaged else None
    return {"intact": False, "messages": writer.count, "topics": {t: e.count for t, e in writer.topics.items()},
            "stopped_at": first.problem if first else "", "kept": kept,
            "damaged_file": first.source.name + ".damaged" if first else ""}
