"""Who answers each lockstep sample and who must hear it first, derived from the graph's own description.

In the deterministic lockstep graph the simulator publishes sample t_k and waits for the command stamped
t_k; before t_0 it waits until its publishers have the matched subscribers its ``wait_for_subscribers``
parameter lists (a topic listed k times needs k), and each commander (controller manager, self-test,
velocity controller, reference publisher) holds its first message until its publisher has N matched
subscribers. Those lists and counts are not written anywhere by hand: they follow from

- the launch document's nodes (package, executable, name, namespace, parameters, remappings), and
- each executable's lockstep *role*, declared once in its package's ``config/lockstep.yaml``
  (:data:`ROLE_FILE`, installed to ``share/<package>/config``)::

      velocity_controller:
        config: velocity_controller        # its parameter defaults: config/velocity_controller.yaml
        hears: [sensors/velocity, thrusters/applied]   # of each sample, from t_0 on
        listens: [velocity_controller/reference]       # others' first messages it must hear
        answers: true                                  # it answers every sample
        gates: {wait_for_command_subscribers: thrusters/command}   # count parameter: the topic it holds
        lifecycle: autostart               # subscribed only once configured: at start if this is true
      mfol_velocity_controller: {like: velocity_controller}

  A simulator declares ``samples`` (the topics it publishes with each sample) and ``sample_gate`` (its
  list parameter); a manager ``configures: {nodes: controllers, when: initial}`` (it configures the nodes
  its parameter ``controllers`` names at start when ``initial`` is not empty); a recorder
  ``heard_parameter: topics`` (its typed ``/topic:pkg/msg/Type`` entries are subscribed at start);

- plus the extra listeners a harness declares (:class:`Listener`: its probe, a recorder, a viewer).

Names are resolved as rcl does: relative to the node's namespace (:data:`seapup_common.topics.NAMESPACE`
when the document gives none), a remapping of the document followed. Pure: no rclpy, no clock; the only
input read is the role files (:func:`package_roles`, :func:`role_book` given the share directories by a
shell), and :func:`roster` takes any role lookup.

Implements the graph-ready handshake of the lockstep protocol (thesis fig. 5.1: the simulator publishes
y(t_k), the controller answers u(t_k)): every node that answers t_0 has heard it.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping

from seapup_common.launch_format import NodeSpec, flat_parameters
from seapup_common.topics import NAMESPACE

__all__ = ["ROLE_FILE", "Role", "Listener", "Roster", "RosterError", "RoleFileError", "UnknownRoleError",
           "NotPublishedError", "resolve", "parse_roles", "package_roles", "role_book", "nodes_of_document",
           "roster", "fill"]

#: The file, in ``share/<package>/config``, that declares the lockstep roles of a package's executables.
ROLE_FILE = "lockstep.yaml"

_ROLE_KEYS = {"config", "hears", "listens", "answers", "samples", "sample_gate", "gates", "lifecycle",
              "configures", "heard_parameter", "like"}


class RosterError(ValueError):
    """A graph whose lockstep roster cannot be derived (the message names the node, topic or file)."""


class RoleFileError(RosterError):
    """A role file (``config/lockstep.yaml``) that is not as :mod:`~seapup_common.lockstep.roster` describes."""


class UnknownRoleError(RosterError):
    """A launch document names an executable whose package declares no lockstep role for it."""


class NotPublishedError(RosterError):
    """A node must hear a per-sample topic that the graph's simulator does not publish."""


@dataclass(frozen=True)
class Role:
    """One executable's part in the lockstep protocol (see the module docstring for the file's keys).

    Parameters
    ----------
    hears : tuple of str
        The per-sample topics it must hear from t_0 on (the simulator waits for it on each).
    listens : tuple of str
        Commanders' topics whose first message it must hear (a commander waits for it).
    answers : bool
        Whether it answers every sample (a command or reference stamped t_k).
    samples : tuple of str
        The topics it publishes with each sample (a simulator).
    sample_gate : str
        Its string-array parameter that lists the awaited subscribers of ``samples`` (a topic k times: k).
    gates : mapping of str to str
        Count parameter -> the topic whose first message it holds until that many subscribers matched.
    lifecycle : str
        A lifecycle node subscribes only once configured: at start when this boolean parameter is true
        (or when a manager configures it, ``configures``); "" for an ordinary node.
    configures : mapping of str to str
        ``{nodes: P, when: Q}``: at start it configures the nodes its parameter P names, when Q is not empty.
    heard_parameter : str
        A string-array parameter that lists more topics it hears; entries ``/topic:pkg/msg/Type`` (typed)
        are subscribed at start and count, untyped ones only later and do not.
    defaults : mapping
        Its parameters' defaults (from the package's ``config/<config>.yaml``), for the ones above.
    """

    hears: tuple[str, ...] = ()
    listens: tuple[str, ...] = ()
    answers: bool = False
    samples: tuple[str, ...] = ()
    sample_gate: str = ""
    gates: Mapping[str, str] = field(default_factory=dict)
    lifecycle: str = ""
    configures: Mapping[str, str] = field(default_factory=dict)
    heard_parameter: str = ""
    defaults: Mapping[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class Listener:
    """A subscriber that is not a node of the launch document: a harness's probe, a recorder, a viewer.

    Parameters
    ----------
    name : str
        For messages and :attr:`Roster.listeners`.
    topics : tuple of str
        What it subscribes to from the start (absolute, or relative to :data:`~seapup_common.topics.NAMESPACE`).
        It counts on those the graph gates (a simulator's per-sample topics, a commander's topic); the rest
        are not waited for.

    Examples
    --------
    >>> Listener.recorder("recorder", ["/seapup/sensors/velocity:geometry_msgs/msg/TwistWithCovarianceStamped",
    ...                                "/tf_static"]).topics
    ('/seapup/sensors/velocity',)
    """

    name: str
    topics: tuple[str, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "topics", tuple(str(t) for t in self.topics))

    @classmethod
    def recorder(cls, name: str, entries: Iterable[str]) -> "Listener":
        """A recorder told ``entries`` (``/topic`` or ``/topic:pkg/msg/Type``): only the typed ones are
        subscribed before any publisher exists, so only they are waited for."""
        return cls(name, tuple(_typed_topics(entries)))


@dataclass(frozen=True)
class Roster:
    """Who answers each sample and who must hear each first message of a graph (:func:`roster`).

    Attributes
    ----------
    listeners : dict
        Topic (resolved) -> the labels of the nodes and listeners that must hear its first message, for
        every topic a node of the graph gates.
    answerers : tuple of str
        The labels of the nodes that answer every sample from t_0 on.
    settings : dict
        Node label -> {parameter: value}: the simulator's ``wait_for_subscribers`` list (each topic as many
        times as it has listeners) and each commander's counts.
    """

    listeners: dict
    answerers: tuple
    settings: dict

    def count(self, topic: str) -> int:
        """How many must hear ``topic``'s first message (0 for a topic nobody gates)."""
        return len(self.listeners.get(resolve(topic, NAMESPACE), ()))


def resolve(name: str, namespace: str = "", remappings: Mapping[str, str] | None = None) -> str:
    """A topic name as rcl resolves it: relative names under ``namespace`` (default
    :data:`~seapup_common.topics.NAMESPACE`), then a matching remapping's target.

    Raises
    ------
    RosterError
        For a private name (``~/x``): roles name topics, not a node's private ones.

    Examples
    --------
    >>> resolve("thrusters/command", "", {"thrusters/command": "/seapup/gmv/thrusters/command"})
    '/seapup/gmv/thrusters/command'
    >>> resolve("/clock", "/other")
    '/clock'
    """
    def absolute(topic: str) -> str:
        if topic.startswith("~"):
            raise RosterError(f"{topic!r}: a private name cannot be a lockstep topic")
        if topic.startswith("/"):
            return topic
        return f"{(namespace or NAMESPACE).rstrip('/')}/{topic}"
    full = absolute(str(name))
    for source, target in (remappings or {}).items():
        if absolute(str(source)) == full:
            return absolute(str(target))
    return full


def _typed_topics(entries) -> list[str]:
    if isinstance(entries, str):
        entries = [entries]
    return [str(e).split(":", 1)[0] for e in entries or () if ":" in str(e)]


def _names(value, what: str) -> tuple[str, ...]:
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise RoleFileError(f"{what}: a list of topic names, got {value!r}")
    return tuple(value)


def _role(name: str, body, source: str, defaults: Callable[[str], Mapping]) -> Role:
    what = f"{source}: {name}"
    if not isinstance(body, dict):
        raise RoleFileError(f"{what}: a mapping of {', '.join(sorted(_ROLE_KEYS))}")
    unknown = sorted(set(body) - _ROLE_KEYS)
    if unknown:
        raise RoleFileError(f"{what}: unknown key {unknown[0]!r} (keys: {', '.join(sorted(_ROLE_KEYS))})")
    for key in ("gates", "configures"):
        if not isinstance(body.get(key, {}), dict):
            raise RoleFileError(f"{what}: {key} is a mapping, got {body[key]!r}")
    if set(body.get("configures", {})) - {"nodes", "when"} or (body.get("configures") and
                                                              set(body["configures"]) != {"nodes", "when"}):
        raise RoleFileError(f"{what}: configures is {{nodes: PARAMETER, when: PARAMETER}}")
    if not isinstance(body.get("answers", False), bool):
        raise RoleFileError(f"{what}: answers is true or false, got {body['answers']!r}")
    if bool(body.get("samples")) != bool(body.get("sample_gate")):
        raise RoleFileError(f"{what}: samples and sample_gate go together")
    return Role(hears=_names(body.get("hears"), f"{what}: hears"),
                listens=_names(body.get("listens"), f"{what}: listens"), answers=bool(body.get("answers", False)),
                samples=_names(body.get("samples"), f"{what}: samples"), sample_gate=str(body.get("sample_gate", "")),
                gates={str(k): str(v) for k, v in body.get("gates", {}).items()},
                lifecycle=str(body.get("lifecycle", "")),
                configures={str(k): str(v) for k, v in body.get("configures", {}).items()},
                heard_parameter=str(body.get("heard_parameter", "")),
                defaults=dict(defaults(str(body["config"])) if body.get("config") else {}))


def parse_roles(document, source: str = "roles", defaults: Callable[[str], Mapping] | None = None) -> dict:
    """The roles of a role file's document (executable -> :class:`Role`), ``like`` entries copied.

    Parameters
    ----------
    document : mapping
        The parsed ``config/lockstep.yaml``.
    source : str
        For messages.
    defaults : callable, optional
        ``config`` name -> that node's parameter defaults (default: none known).

    Raises
    ------
    RoleFileError
        For an unknown key, a wrong type, or ``like`` naming an executable the document does not declare.
    """
    if not isinstance(document, dict):
        raise RoleFileError(f"{source}: a mapping of executable names to roles")
    lookup = defaults or (lambda _config: {})
    roles = {name: _role(name, body, source, lookup) for name, body in document.items()
             if not (isinstance(body, dict) and "like" in body)}
    for name, body in document.items():
        if isinstance(body, dict) and "like" in body:
            if set(body) != {"like"} or body["like"] not in roles:
                raise RoleFileError(f"{source}: {name}: like names another executable of the file, alone")
            roles[name] = roles[body["like"]]
    return roles


def package_roles(config_dir: str | Path) -> dict:
    """The roles a package declares in ``config_dir/lockstep.yaml`` (its installed ``share/<package>/config``;
    none if the file is absent), each with the defaults of its ``config`` parameter file there.

    Raises
    ------
    RoleFileError
        For a role file, or a parameter file it names, that cannot be read or parsed.
    """
    from seapup_common.input_files import InputFileError, load_yaml_file
    from seapup_common.parameters import load_node_parameters
    config_dir = Path(config_dir)
    path = config_dir / ROLE_FILE
    if not path.is_file():
        return {}
    try:
        document = load_yaml_file(path, "config")
    except InputFileError as exc:
        raise RoleFileError(str(exc)) from None

    def defaults(config: str) -> dict:
        try:
            return flat_parameters(load_node_parameters(config_dir / f"{config}.yaml", config))
        except ValueError as exc:
            raise RoleFileError(f"{path}: config {config!r}: {exc}") from None
    return parse_roles(document, str(path), defaults)


def role_book(share: Callable[[str], str | Path | None]) -> Callable[[str, str], Role | None]:
    """A role lookup ``(package, executable) -> Role or None`` over installed packages, each package's file
    read once.

    Parameters
    ----------
    share : callable
        Package name -> its share directory, or None for a package not installed (a shell passes the ament
        index's lookup: this module reads files but never the ROS environment).
    """
    cache: dict[str, dict] = {}

    def lookup(package: str, executable: str) -> Role | None:
        if package not in cache:
            where = share(package)
            cache[package] = package_roles(Path(where) / "config") if where is not None else {}
        return cache[package].get(executable)
    return lookup


def _given(spec: NodeSpec) -> dict:
    """The parameters the document gives the node (:meth:`NodeSpec.given_parameters`)."""
    return spec.given_parameters()


def nodes_of_document(document) -> list[NodeSpec]:
    """The nodes of a launch document as :func:`seapup_common.launch_format.launch_document` writes it
    (literal values; a file with arguments and substitutions is read by
    :func:`seapup_common.ros.launch_graph.load_graph`).

    Raises
    ------
    RosterError
        For a document that is not ``{launch: [...]}`` or holds a substitution ``$(...)``.
    """
    if not isinstance(document, Mapping) or not isinstance(document.get("launch"), list):
        raise RosterError("a launch document is a mapping 'launch:' holding a list")
    if "$(" in repr(document):
        raise RosterError("the document holds substitutions $(...): read it with launch_graph.load_graph")

    def parameters(entries, prefix="") -> dict:
        out = {}
        for entry in entries:
            if "param" in entry:
                out.update(parameters(entry["param"], f"{prefix}{entry['name']}."))
            elif "name" in entry:
                out[f"{prefix}{entry['name']}"] = entry["value"]
        return out
    nodes = []
    for entry in document["launch"]:
        body = entry.get("node") if isinstance(entry, Mapping) else None
        if body is None:
            continue
        nodes.append(NodeSpec(package=str(body["pkg"]), executable=str(body["exec"]), name=str(body.get("name", "")),
                              namespace=str(body.get("namespace", "")),
                              parameters=[parameters(body.get("param") or [])],
                              remappings={str(r["from"]): str(r["to"]) for r in body.get("remap") or []}))
    return nodes


def roster(nodes: Iterable[NodeSpec | Mapping], listeners: Iterable[Listener] = (), *,
           roles: Callable[[str, str], Role | None]) -> Roster:
    """The lockstep roster of a graph: who answers each sample, who must hear each first message, and the
    parameters that say so.

    A topic's listeners are the nodes whose role hears (or listens to) it -- a lifecycle node only if it is
    configured at start -- and the extra ``listeners`` that subscribe to it; a simulator's
    ``wait_for_subscribers`` lists each of its per-sample topics once per listener, a commander's count is
    its topic's listeners.

    Parameters
    ----------
    nodes : iterable of NodeSpec or mapping
        The graph (:func:`~seapup_common.ros.launch_graph.load_graph`'s nodes, or mappings of NodeSpec fields).
    listeners : iterable of Listener
        Subscribers outside the document.
    roles : callable
        ``(package, executable) -> Role or None``: the installed packages' (:func:`role_book`) or a test's.

    Returns
    -------
    Roster

    Raises
    ------
    UnknownRoleError
        For a node whose executable has no declared role.
    NotPublishedError
        For a node that must hear a per-sample topic the graph's simulator does not publish.

    Examples
    --------
    >>> sim = Role(samples=("sensors/velocity",), sample_gate="wait_for_subscribers", listens=("thrusters/command",))
    >>> law = Role(hears=("sensors/velocity",), answers=True, gates={"wait_for_command_subscribers": "thrusters/command"})
    >>> book = {"simulator": sim, "law": law}
    >>> r = roster([NodeSpec("p", "simulator"), NodeSpec("p", "law")], [Listener("probe", ("sensors/velocity",))],
    ...            roles=lambda package, executable: book.get(executable))
    >>> r.settings["simulator"], r.settings["law"], r.answerers
    ({'wait_for_subscribers': ['/seapup/sensors/velocity', '/seapup/sensors/velocity']}, {'wait_for_command_subscribers': 1}, ('law',))
    """
    lookup = roles
    specs = [n if isinstance(n, NodeSpec) else NodeSpec(**n) for n in nodes]
    cast = []
    for spec in specs:
        role = lookup(spec.package, spec.executable)
        if role is None:
            raise UnknownRoleError(f"node {spec.label}: {spec.package} declares no lockstep role for the executable "
                                   f"{spec.executable!r} (add it to {spec.package}'s config/{ROLE_FILE})")
        cast.append((spec, role, {**role.defaults, **_given(spec)}))

    managed = set()   # lifecycle nodes a manager configures at start
    for spec, role, values in cast:
        if role.configures and values.get(role.configures["when"]):
            managed.update(str(n) for n in values.get(role.configures["nodes"]) or ())

    def subscribed(spec, role, values) -> bool:
        return not role.lifecycle or bool(values.get(role.lifecycle)) or spec.label in managed

    def names(spec, topics) -> list[str]:
        return [resolve(t, spec.namespace, spec.remappings) for t in topics]

    published = {t for spec, role, _ in cast for t in names(spec, role.samples)}
    gated = set(published) | {t for spec, role, _ in cast for t in names(spec, role.gates.values())}
    heard: dict[str, list[str]] = {}
    for spec, role, values in cast:
        if not subscribed(spec, role, values):
            continue
        samples = names(spec, role.hears)
        missing = [t for t in samples if published and t not in published]
        if missing:
            raise NotPublishedError(f"node {spec.label} ({spec.executable}) must hear {missing[0]}, which the graph's "
                                    f"simulator does not publish ({', '.join(sorted(published))})")
        extra = _typed_topics(values.get(role.heard_parameter)) if role.heard_parameter else []
        for topic in dict.fromkeys([*samples, *names(spec, role.listens), *names(spec, extra)]):
            heard.setdefault(topic, []).append(spec.label)
    for listener in listeners:
        for topic in dict.fromkeys(resolve(t) for t in listener.topics):
            heard.setdefault(topic, []).append(listener.name)

    settings: dict[str, dict] = {}
    for spec, role, _ in cast:
        own = {}
        awaited = [t for t in names(spec, role.samples) for who in heard.get(t, ()) if who != spec.label]
        if awaited:   # none: the parameter's default (an empty list, which -p cannot spell with its type)
            own[role.sample_gate] = awaited
        for parameter, topic in role.gates.items():
            own[parameter] = sum(who != spec.label for who in heard.get(resolve(topic, spec.namespace,
                                                                               spec.remappings), ()))
        if own:
            settings[spec.label] = own
    answerers = tuple(spec.label for spec, role, values in cast if role.answers and subscribed(spec, role, values))
    return Roster(listeners={t: tuple(who) for t, who in heard.items() if t in gated}, answerers=answerers,
                  settings=settings)


def fill(nodes: Iterable[NodeSpec], plan: Roster) -> list[NodeSpec]:
    """The nodes with the roster's parameters added, except where the document gives a parameter itself
    (a hand-written graph keeps its own value).

    Examples
    --------
    >>> plan = Roster(listeners={}, answerers=(), settings={"law": {"wait_for_command_subscribers": 2}})
    >>> fill([NodeSpec("p", "law", parameters=[{"lockstep": True}])], plan)[0].parameters
    [{'lockstep': True}, {'wait_for_command_subscribers': 2}]
    """
    out = []
    for spec in nodes:
        given = _given(spec)
        added = {k: v for k, v in plan.settings.get(spec.label, {}).items() if k not in given}
        have = spec.parameters if isinstance(spec.parameters, list) else [spec.parameters]
        out.append(dataclasses.replace(spec, parameters=[*have, added]) if added else spec)
    return out
