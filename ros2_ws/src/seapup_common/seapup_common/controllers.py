"""Velocity controllers by name: a registry of control laws, looked up through package entry points.

A control law is data to everything above the contract: a
:class:`ControllerSpec` names a registered *type* (``"mfol"``, ``"hold"``, ...)
and carries its parameters (and, where the law is designed offline, the
design document, e.g. a self-test's gains); :func:`create_controller` turns it
into a :class:`~seapup_common.contract.VelocityController`. Nodes, runners
and the command line never import a law: they look it up here, as
ros2_control loads a controller plugin by its type string.

A package registers a law with an entry point in the group
:data:`ENTRY_POINT_GROUP` naming a :class:`ControllerType`::

    # setup.py of the package that defines the law
    entry_points={"seapup.velocity_controllers": [
        "mfol = seapup_control.mfol_controller:MFOL_TYPE"]}

so a new law needs no edit of the simulator, the nodes, the runners or the
CLI. Tests and scripts may also :func:`register_controller` a type in the
running process.
"""
from __future__ import annotations

import math
import types
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, Callable


from seapup_common.blade_pitch import BLADE_PITCH_LIMIT
from seapup_common.contract import ContractError, HoldCommand, VelocityController
from seapup_common.values import finite_real, is_real

__all__ = ["at_input_limit", "ENTRY_POINT_GROUP", "ControllerRegistryError", "Ranged", "ControllerType", "ControllerSpec", "register_controller",
           "controller_type", "available_controllers", "create_controller", "HOLD_TYPE"]

#: The entry-point group packages register their control laws in.
ENTRY_POINT_GROUP = "seapup.velocity_controllers"


class ControllerRegistryError(ValueError):
    """An unknown controller type, unknown or malformed parameters, or a design document it cannot use."""


@dataclass(frozen=True)
class Ranged:
    """A law parameter's default with the range it may take (a number, or each number of a list) and why.

    Declared in place of the bare default in :attr:`ControllerType.parameters`, so the range sits next to
    the default it bounds::

        {"forgetting": Ranged(0.999, 0.9, 1.0, "eq. 6.13: lambda in (0, 1]; ...")}

    Parameters
    ----------
    default : number or list
        The default (its type is the type accepted).
    low, high : float
        The closed interval allowed; NaN and inf are never allowed.
    source : str
        Where the range comes from (a thesis section, a physical bound, a choice and its reason).
    """

    default: Any
    low: float
    high: float
    source: str

    def __post_init__(self):
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low <= self.high):
            raise ControllerRegistryError(f"a parameter range is two finite numbers low <= high, got "
                                          f"[{self.low!r}, {self.high!r}]")
        if not self.source:
            raise ControllerRegistryError("a parameter range says where it comes from (source)")


@dataclass(frozen=True)
class ControllerType:
    """A registered control law.

    Parameters
    ----------
    name : str
        The type string a :class:`ControllerSpec` names.
    factory : callable
        ``factory(parameters, document, sample_period) -> VelocityController``: ``parameters`` is the
        complete mapping (defaults filled in), ``document`` the design document (a mapping) or None,
        ``sample_period`` the period the caller samples at [s] or None (the law's own, e.g. the
        period its gains were designed for). It raises ``ValueError`` (or a subclass) on what it
        cannot use.
    parameters : mapping
        Every parameter the law takes with its default (the type of the default is the type
        accepted); a spec naming another is refused.
    description : str
        One line for listings.
    needs_document : bool
        The law cannot be built without a design document (a controller file).
    needs_applied : bool
        The law estimates from the blade pitch actually applied over each interval, so a lockstep
        transport must deliver it before the sample is answered (see :mod:`seapup_common.lockstep`).

    Attributes
    ----------
    ranges : mapping
        ``name: (low, high)`` of each parameter declared :class:`Ranged` (for a list: of each element);
        :meth:`complete` and the velocity controller node refuse a value outside it.
    sources : mapping
        ``name: source`` of each range.
    """

    name: str
    factory: Callable[[dict, Mapping | None, float | None], VelocityController]
    parameters: Mapping = field(default_factory=dict)
    description: str = ""
    needs_document: bool = False
    needs_applied: bool = False
    ranges: Mapping = field(default_factory=dict, compare=False)
    sources: Mapping = field(default_factory=dict, compare=False)

    def __post_init__(self):
        defaults, ranges, sources = {}, dict(self.ranges), dict(self.sources)
        for name, value in dict(self.parameters).items():
            if isinstance(value, Ranged):
                defaults[name] = value.default
                ranges[name], sources[name] = (float(value.low), float(value.high)), value.source
            else:
                defaults[name] = value
        object.__setattr__(self, "parameters", types.MappingProxyType(defaults))
        object.__setattr__(self, "ranges", types.MappingProxyType(ranges))
        object.__setattr__(self, "sources", types.MappingProxyType(sources))
        for name, default in defaults.items():
            if name in ranges:
                _within(self.name, name, default, ranges[name])

    def complete(self, parameters: Mapping | None) -> dict:
        """The parameters with defaults filled in; unknown names or wrong types refused.

        Raises
        ------
        ControllerRegistryError
            Naming the offending parameter and what is accepted.
        """
        given = dict(parameters or {})
        unknown = sorted(set(given) - set(self.parameters))
        if unknown:
            known = ", ".join(sorted(self.parameters)) or "none"
            raise ControllerRegistryError(f"controller type {self.name!r} has no parameter(s) {unknown}; "
                                          f"it takes: {known}")
        out = dict(self.parameters)
        for name, value in given.items():
            out[name] = _coerce(self.name, name, value, self.parameters[name])
            if name in self.ranges:
                _within(self.name, name, out[name], self.ranges[name])
        return out


def _within(kind: str, name: str, value, bounds) -> None:
    """Raise unless ``value`` (each element of a list) is finite and within ``bounds``."""
    lo, hi = bounds
    for v in value if isinstance(value, (list, tuple)) else [value]:
        if is_real(v) and not (finite_real(v) is not None and lo <= v <= hi):
            raise ControllerRegistryError(f"controller {kind!r} parameter {name!r} = {value!r} refused: it must be "
                                          f"finite and within [{lo:g}, {hi:g}]")


def _coerce(kind: str, name: str, value, default):
    """``value`` as the type of ``default`` (bool, int, float, str, list of floats), or raise."""
    where = f"controller {kind!r} parameter {name!r}"
    if isinstance(default, bool):
        if isinstance(value, bool):
            return value
        raise ControllerRegistryError(f"{where} must be true or false, got {value!r}")
    if isinstance(default, (int, float)) and not isinstance(default, bool):
        if finite_real(value) is None:
            raise ControllerRegistryError(f"{where} must be a finite number, got {value!r}"[:300])
        if isinstance(default, int):
            if not float(value).is_integer():
                raise ControllerRegistryError(f"{where} must be a whole number, got {value!r}")
            return int(value)
        return float(value)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise ControllerRegistryError(f"{where} must be a string, got {value!r}")
        return value
    if isinstance(default, (list, tuple)):
        if not isinstance(value, (list, tuple)) or not all(is_real(v) for v in value):
            raise ControllerRegistryError(f"{where} must be a list of numbers, got {value!r}"[:300])
        values = [finite_real(v) for v in value]
        if any(v is None for v in values):
            raise ControllerRegistryError(f"{where} must be finite numbers, got {value!r}"[:300])
        if default and len(values) != len(default):
            raise ControllerRegistryError(f"{where} needs {len(default)} values, got {len(values)}")
        return values
    return value


@dataclass(frozen=True)
class ControllerSpec:
    """Which control law, with what: plain data (picklable, JSON-able).

    Parameters
    ----------
    type : str
        A registered controller type (:func:`available_controllers`).
    parameters : mapping
        The law's parameters (:attr:`ControllerType.parameters`); missing ones take their defaults.
    file : str, optional
        Path of a design document (YAML), e.g. the controller file a self-test writes.
    document : mapping, optional
        The design document itself (wins over ``file``): a run carries its designed gains inline.

    Examples
    --------
    >>> spec = ControllerSpec("hold", {"blade_pitch": [0.0, 0.0, 0.1, 0.1]})
    >>> controller = create_controller(spec, sample_period=0.2)
    >>> controller.sample_period, controller.blade_pitch.tolist()
    (0.2, [0.0, 0.0, 0.1, 0.1])
    """

    type: str
    parameters: Mapping = field(default_factory=dict)
    file: str | None = None
    document: Mapping | None = None

    def __post_init__(self):
        if not isinstance(self.type, str) or not self.type:
            raise ControllerRegistryError(f"a controller type is a non-empty string, got {self.type!r}")
        if not isinstance(self.parameters, Mapping):
            raise ControllerRegistryError(f"controller parameters must be a mapping, got {self.parameters!r}")
        object.__setattr__(self, "parameters", dict(self.parameters))
        if self.file is not None:
            object.__setattr__(self, "file", str(self.file))

    def load_document(self) -> Mapping | None:
        """The design document: inline, else read from ``file``, else None.

        Raises
        ------
        ControllerRegistryError
            If the file cannot be read or is not a YAML mapping.
        """
        if self.document is not None:
            return self.document
        if not self.file:
            return None
        from seapup_common.input_files import InputFileError, load_yaml_file
        try:   # bounded and strict: at most 1 MiB, no duplicated key, no !!python tag
            document = load_yaml_file(self.file, "config")
        except InputFileError as exc:
            raise ControllerRegistryError(f"controller file {exc}") from None
        if not isinstance(document, Mapping):
            raise ControllerRegistryError(f"controller file {self.file!r} is not a YAML mapping")
        return document

    def to_dict(self) -> dict:
        """Plain data: ``{"type", "parameters", "file", "document"}`` (None fields left out)."""
        out: dict[str, Any] = {"type": self.type, "parameters": dict(self.parameters)}
        if self.file is not None:
            out["file"] = self.file
        if self.document is not None:
            out["document"] = dict(self.document)
        return out

    @classmethod
    def from_dict(cls, data: Mapping) -> "ControllerSpec":
        """The inverse of :meth:`to_dict` (unknown keys refused)."""
        if isinstance(data, str):
            return cls(data)
        if not isinstance(data, Mapping):
            raise ControllerRegistryError(f"a controller is a type name or a mapping, got {data!r}")
        unknown = sorted(set(data) - {"type", "parameters", "file", "document"})
        if unknown:
            raise ControllerRegistryError(f"unknown controller key(s) {unknown}; known: type, parameters, file, "
                                          "document")
        if "type" not in data:
            raise ControllerRegistryError("a controller needs its 'type'")
        return cls(data["type"], data.get("parameters") or {}, data.get("file"), data.get("document"))


# -- the registry ---------------------------------------------------------------------------
_REGISTERED: dict[str, ControllerType] = {}


def register_controller(kind: ControllerType, *, replace: bool = False) -> ControllerType:
    """Register a control law in this process (entry points register installed ones).

    Raises
    ------
    ControllerRegistryError
        If the name is taken (by another registration or an entry point) and ``replace`` is false.
    """
    if not isinstance(kind, ControllerType):
        raise ControllerRegistryError(f"register a ControllerType, got {type(kind).__name__}")
    if not replace and kind.name in _REGISTERED and _REGISTERED[kind.name] is not kind:
        raise ControllerRegistryError(f"controller type {kind.name!r} is already registered")
    _REGISTERED[kind.name] = kind
    return kind


def _entry_points() -> dict[str, metadata.EntryPoint]:
    found = {}
    for entry in metadata.entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(entry.name, entry)  # the first on the path wins, as for console scripts
    return found


def available_controllers() -> list[str]:
    """Every controller type name: registered in this process or by an installed package."""
    return sorted(set(_REGISTERED) | set(_entry_points()))


def at_input_limit(kind: "ControllerType", parameters: Mapping, input_limit: float) -> dict:
    """A law's ``parameters`` with its ``blade_pitch_limit`` at the vehicle's ``input_limit`` (a node's
    ``input_limit`` parameter, a run's vehicle): the law saturates, and winds back, where the vehicle does; 0
    leaves the law's own (the Seapup's blade-pitch limit by default)."""
    out = dict(parameters)
    if input_limit > 0.0 and "blade_pitch_limit" in kind.parameters:
        out["blade_pitch_limit"] = float(input_limit)
    return out


def controller_type(name: str) -> ControllerType:
    """The registered :class:`ControllerType` called ``name``.

    Raises
    ------
    ControllerRegistryError
        If nothing is registered under that name (the message lists what is), or an entry point
        does not load a :class:`ControllerType`.
    """
    if name in _REGISTERED:
        return _REGISTERED[name]
    entry = _entry_points().get(name)
    if entry is None:
        raise ControllerRegistryError(f"no controller type {name!r}; available: "
                                      f"{', '.join(available_controllers()) or 'none'}")
    try:
        kind = entry.load()
    except Exception as exc:  # noqa: BLE001 - a broken plugin must not take the caller down
        raise ControllerRegistryError(f"controller type {name!r} ({entry.value}) does not load: {exc}") from None
    if not isinstance(kind, ControllerType) or kind.name != name:
        raise ControllerRegistryError(f"entry point {name!r} ({entry.value}) is not a ControllerType named {name!r}")
    _REGISTERED.setdefault(name, kind)
    return kind


def create_controller(spec: ControllerSpec | Mapping | str, sample_period: float | None = None) -> VelocityController:
    """Build the controller a spec describes.

    Parameters
    ----------
    spec : ControllerSpec, mapping or str
        The law (a mapping as :meth:`ControllerSpec.to_dict`, a bare type name for defaults).
    sample_period : float, optional
        The period the caller samples at [s]; None: the law's own (its design document's).

    Returns
    -------
    VelocityController
        Not yet reset: the caller starts it bumpless from the applied command.

    Raises
    ------
    ControllerRegistryError
        On an unknown type, unknown or malformed parameters, a missing or unusable design document,
        or a law whose sample period differs from ``sample_period``.
    """
    if not isinstance(spec, ControllerSpec):
        spec = ControllerSpec.from_dict(spec)
    kind = controller_type(spec.type)
    parameters = kind.complete(spec.parameters)
    document = spec.load_document()
    if kind.needs_document and document is None:
        raise ControllerRegistryError(f"controller type {kind.name!r} needs a design document (a controller file)")
    if sample_period is not None and not (math.isfinite(sample_period) and sample_period > 0):
        raise ControllerRegistryError(f"sample period must be finite and > 0 s, got {sample_period!r}")
    try:
        controller = kind.factory(parameters, document, sample_period)
    except ControllerRegistryError:
        raise
    except (ValueError, KeyError, TypeError) as exc:
        raise ControllerRegistryError(f"controller {kind.name!r}: {exc}") from None
    if not isinstance(controller, VelocityController):
        raise ControllerRegistryError(f"controller type {kind.name!r} made a {type(controller).__name__}, "
                                      "not a VelocityController")
    if sample_period is not None and abs(controller.sample_period - sample_period) > 1e-9:
        raise ControllerRegistryError(f"controller {kind.name!r} samples every {controller.sample_period:g} s, "
                                      f"asked for {sample_period:g} s")
    return controller


def _hold(parameters: dict, document, sample_period: float | None) -> HoldCommand:
    if sample_period is None:
        raise ControllerRegistryError("the hold controller needs the sample period of its caller")
    try:
        return HoldCommand(parameters["blade_pitch"] or None, sample_period)
    except ContractError as exc:
        raise ControllerRegistryError(f"hold: {exc}") from None


#: Hold one blade-pitch setting (an open loop; :class:`~seapup_common.contract.HoldCommand`): four pitches
#: [rad], or none to hold what is applied when it starts.
HOLD_TYPE = ControllerType("hold", _hold, types.MappingProxyType({
    "blade_pitch": Ranged([], -BLADE_PITCH_LIMIT, BLADE_PITCH_LIMIT, "the blade-pitch limit, +/-35 deg (sec. 3.1)")}),
                           "hold one blade-pitch setting [rad] (open loop); blade_pitch [] (the default): the one "
                           "applied when it starts")
