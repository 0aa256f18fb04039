"""The Seapup's 6-DOF nonlinear equations of motion (thesis ch. 2).

State (12,): ``[x, y, z, phi, theta, psi, u, v, w, p, q, r]`` -- position of
the body origin in the NED world frame ``odom_ned`` [m], Euler angles (roll,
pitch, yaw; z-y-x convention) [rad], and body velocities in the FRD body frame
``base_link_frd`` [m/s, rad/s]. Input (4,): blade pitches [rad] in
``seapup_msgs/BladePitch`` order.

The equations are eq. 2.3::

    M_hat Q_dot = F_d(Q) + H_hat(Q_r) + G(phi, theta, psi) + T + U

- ``M_hat`` = rigid-body mass matrix about an arbitrary origin (CG offset and
  full inertia; eq. 2.8, 2.17a) plus the symmetric added-mass matrix (Newman,
  sec. 3.4; the acceleration derivatives moved to the left, sec. 2.3.1);
- ``F_d`` = rigid-body Coriolis/centripetal forces about the origin (the
  velocity terms of eq. 2.8 and 2.17a);
- ``H_hat`` = added-mass Coriolis forces plus the table of slow-motion
  derivatives (:mod:`seapup_sim.hydrodynamics`), all on velocities relative to
  the water (u, v, w relative; p, q, r absolute, sec. 2.3.1);
- ``G`` = weight at the CG and buoyancy at the CB (sec. 2.3.2);
- ``T`` = the four thrusters (:mod:`seapup_sim.thrusters`);
- ``U`` = an external wrench (umbilical, later issues), body axes.

Kinematics (eq. 2.1, 2.2): the NED position rate is R(phi, theta, psi) times
the linear body velocity, the Euler rates are T(phi, theta) times (p, q, r).

Payloads (the camera of sec. 3.6) are composed into mass, CG, CB, inertia and
added mass from their own mass, buoyancy, position and shape, so an overlay
only states the payload.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from seapup_common.frames import rotation_body_to_ned
from seapup_common.config import ConfigError, ConfigView
from seapup_sim.hydrodynamics import HydroTable
from seapup_sim.inputs import inputs_of
from seapup_sim.thrusters import THRUSTER_KINDS, FixedPitchThrusters, ThrustCurve, ThrusterSet

__all__ = ["cross", "kirchhoff_coriolis", "skew", "rotation_body_to_ned", "euler_rate_matrix", "specific_force",
           "VehicleModel", "STATE_NAMES"]

STATE_NAMES = ("x", "y", "z", "phi", "theta", "psi", "u", "v", "w", "p", "q", "r")


def cross(a, b) -> np.ndarray:
    """a x b for 3-vectors (np.cross is ~10x slower for single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def kirchhoff_coriolis(mass: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Coriolis/centripetal generalized force of a symmetric 6x6 mass matrix.

    With p = M nu split into linear and angular parts (p_v, p_w) and nu into
    (v, w): ``-[w x p_v ; w x p_w + v x p_v]`` (Kirchhoff's equations; Fossen,
    Thm 3.2). It does no work: nu . f = 0.
    """
    a, b, c, d, e, f = (mass @ nu).tolist()
    u, v, w, p, q, r = nu.tolist()
    return np.array([
        -(q * c - r * b), -(r * a - p * c), -(p * b - q * a),
        -(q * f - r * e) - (v * c - w * b), -(r * d - p * f) - (w * a - u * c), -(p * e - q * d) - (u * b - v * a),
    ])


def skew(a) -> np.ndarray:
    """Cross-product matrix S(a) with S(a) b = a x b."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def specific_force(state, accel_body, g: float) -> np.ndarray:
    """What an accelerometer at the body origin feels, body axes [m/s^2].

    f = d(u, v, w)/dt + omega x (u, v, w) - g R^T e_z: the acceleration of the
    origin in the NED frame (eq. 2.3's left side, linear part) less gravity,
    expressed in body axes (R of eq. 2.1). At rest and level f = (0, 0, -g).

    Parameters
    ----------
    state : array_like, shape (12,)
    accel_body : array_like, shape (3,)
        d(u, v, w)/dt [m/s^2].
    g : float
        Gravity [m/s^2] (the configuration's ``environment.g``).
    """
    # in plain floats, term by term in the order of ``accel + cross(omega, v) - g * R[2]`` on arrays (the same bits
    # at a third of the cost: the simulator computes it every sample)
    x = np.asarray(state, float)
    phi, theta = float(x[3]), float(x[4])
    u, v, w, p, q, r = x[6:12].tolist()
    a, b, c = np.asarray(accel_body, float).tolist()
    cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    g = float(g)
    return np.array([a + (q * w - r * v) - g * -st, b + (r * u - p * w) - g * (ct * sf),
                     c + (p * v - q * u) - g * (ct * cf)])


def euler_rate_matrix(phi: float, theta: float) -> np.ndarray:
    """T with (phi, theta, psi)_dot = T (p, q, r) (eq. 2.2); singular at theta = +/-90 deg."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, tt = math.cos(theta), math.tan(theta)
    return np.array([[1.0, sf * tt, cf * tt], [0.0, cf, -sf], [0.0, sf / ct, cf / ct]])


def _point_mass_added_mass(added: float, position) -> np.ndarray:
    """6x6 added mass about the origin of a body with isotropic translational
    added mass ``added`` centred at ``position`` (a sphere: no rotational part
    about its own centre)."""
    h = np.zeros((3, 6))
    h[:, :3] = np.eye(3)
    h[:, 3:] = -skew(position)  # velocity of the point: v + w x r = v - S(r) w
    m = added * h.T @ h
    return 0.5 * (m + m.T)  # symmetric by construction; drop rounding asymmetry


@dataclass
class MassProperties:
    """Mass, buoyancy and their centres, inertia about the origin."""

    mass: float
    buoyancy_mass: float
    cg: np.ndarray
    cb: np.ndarray
    inertia_origin: np.ndarray
    added_mass: np.ndarray = field(repr=False)


def compose_mass_properties(rigid: dict, added_mass, payloads, rho: float) -> MassProperties:
    """Combine the vehicle's rigid body and added mass with payloads.

    Each payload: ``mass`` [kg], ``buoyancy_mass`` [kg of displaced water],
    ``position`` [m, body axes], ``radius`` [m] (solid sphere; its added mass is
    the inviscid value rho V / 2 in every direction).
    """
    m = float(rigid["mass"])
    b = float(rigid["buoyancy_mass"])
    cg = np.asarray(rigid["cg"], float)
    cb = np.asarray(rigid["cb"], float)
    inertia_cg = np.asarray(rigid["inertia_cg"], float).reshape(3, 3)
    s = skew(cg)
    inertia = inertia_cg - m * s @ s  # parallel axes to the origin
    ma = np.asarray(added_mass, float).reshape(6, 6).copy()
    m_moment, b_moment = m * cg, b * cb
    for p in payloads or ():
        pm, pb = float(p["mass"]), float(p["buoyancy_mass"])
        pos = np.asarray(p["position"], float)
        radius = float(p["radius"])
        sp = skew(pos)
        inertia = inertia + 0.4 * pm * radius ** 2 * np.eye(3) - pm * sp @ sp
        m_moment = m_moment + pm * pos
        b_moment = b_moment + pb * pos
        m, b = m + pm, b + pb
        volume = 4.0 / 3.0 * np.pi * radius ** 3
        ma = ma + _point_mass_added_mass(0.5 * rho * volume, pos)
    return MassProperties(m, b, m_moment / m, b_moment / b, inertia, ma)


class VehicleModel:
    """Equations of motion of one vehicle configuration.

    Parameters
    ----------
    config : dict
        A vehicle configuration (see ``seapup_sim/vehicles/baseline.yaml``),
        usually from :func:`seapup_sim.vehicle_config.load_vehicle_config`.
    """

    def __init__(self, config: dict):
        self.configure(config)

    def configure(self, config: dict) -> None:
        """(Re)build the model from a configuration; the state lives elsewhere,
        so a configuration can be switched while a simulation runs.

        A missing or malformed key raises :class:`~seapup_common.config.ConfigError`
        naming the configuration and the key."""
        raw = config.raw() if isinstance(config, ConfigView) else config
        config = ConfigView(raw, f"vehicle configuration {raw.get('name', 'unnamed')!r}")
        env = config["environment"]
        self.rho = env.number("rho", lo=0.0, lo_open=True)
        self.g = env.number("g", lo=0.0, lo_open=True)
        self.config_name = config.get("name", "unnamed")
        self.mass_properties = compose_mass_properties(config["rigid_body"], config["added_mass"],
                                            config.get("payloads"), self.rho)
        mp = self.mass_properties
        m_rb = np.zeros((6, 6))
        m_rb[:3, :3] = mp.mass * np.eye(3)
        m_rb[:3, 3:] = -mp.mass * skew(mp.cg)
        m_rb[3:, :3] = mp.mass * skew(mp.cg)
        m_rb[3:, 3:] = mp.inertia_origin
        self.m_rigid = m_rb
        self.m_added = mp.added_mass
        self.m_total = m_rb + mp.added_mass
        self.m_inv = np.linalg.inv(self.m_total)
        self.weight = mp.mass * self.g
        self.buoyancy = mp.buoyancy_mass * self.g
        self._hydrostatic_arm = tuple(self.weight * mp.cg - self.buoyancy * mp.cb)
        self.hydro = HydroTable(config["hydrodynamics"].raw())
        th = config["thrusters"]
        kind = th.get("kind", "controllable_pitch")
        if kind not in THRUSTER_KINDS:
            raise ConfigError(f"{config.source}: thrusters.kind must be one of {', '.join(THRUSTER_KINDS)}, "
                              f"got {str(kind)[:40]!r}")
        try:
            if kind == "fixed_pitch":
                curve = th["thrust_curve"].raw()
                self.thrusters = FixedPitchThrusters(
                    positions=th["positions"], directions=th["directions"],
                    curve=ThrustCurve(curve.get("polynomial"), curve.get("table"),
                                      th.number("deadband", 0.0, lo=0.0)))
            else:
                self.thrusters = ThrusterSet(
                    rho=self.rho, shaft_speed=th["shaft_speed"], diameter=th["diameter"],
                    k_beta=th["k_beta"], k_j=th["k_j"],
                    zero_thrust_pitch=np.radians(th.number("zero_thrust_pitch_deg")),
                    positions=th["positions"], directions=th["directions"], installation=th["installation"],
                    rotation=th["rotation"], torque_ratio=th["torque_ratio"],
                    momentum_drag_factor=th.number("momentum_drag_factor", 1.0, lo=0.0),
                    momentum_drag_epsilon=th.number("momentum_drag_epsilon", 0.005, lo=0.0, lo_open=True))
            self.thrusters.set_efficiency(config.get("thruster_efficiency", [1.0] * self.thrusters.count))
            #: the four inputs a velocity autopilot commands and how they reach the thrusters
            self.inputs = inputs_of(self.thrusters, raw.get("inputs"))
        except ValueError as exc:
            raise ConfigError(f"{config.source}: {exc}") from None
        #: the inputs' limit: the Seapup's blade pitches [rad] (seapup_common/data/interface.yaml), or a virtual
        #: input's full scale, 1
        self.pitch_limit = self.inputs.limit
        self.actuator_time_constant = th.number("actuator_time_constant", lo=0.0)
        self.config = raw
        #: counts configure() calls: a packed copy of the model (the compiled kernels') is stale when it changed
        self.revision = getattr(self, "revision", 0) + 1

    # -- force terms ------------------------------------------------------
    def rigid_coriolis(self, nu: np.ndarray) -> np.ndarray:
        """F_d: rigid-body Coriolis/centripetal forces about the origin (eq. 2.8, 2.17a).

        Computed in Kirchhoff form with the rigid-body mass matrix (equal to the
        velocity terms of eq. 2.8 and 2.17a for a body about an arbitrary origin;
        Fossen, Thm 3.2); the tests check it against eq. 2.8/2.17a written out.
        """
        return kirchhoff_coriolis(self.m_rigid, nu)

    def added_mass_coriolis(self, nu_r: np.ndarray) -> np.ndarray:
        """Coriolis/centripetal forces of the added mass (Kirchhoff), relative velocities."""
        return kirchhoff_coriolis(self.m_added, nu_r)

    def hydrostatics(self, phi: float, theta: float) -> np.ndarray:
        """G: weight at the CG and buoyancy at the CB in body axes (sec. 2.3.2)."""
        return self._hydrostatics_from(np.array([-np.sin(theta), np.cos(theta) * np.sin(phi),
                                                 np.cos(theta) * np.cos(phi)]))

    def _hydrostatics_from(self, down: np.ndarray) -> np.ndarray:
        """Hydrostatics for the NED down axis expressed in body axes: force
        (W - B) down, moment (W r_G - B r_B) x down."""
        dx, dy, dz = down
        net = self.weight - self.buoyancy
        ax, ay, az = self._hydrostatic_arm
        return np.array([net * dx, net * dy, net * dz,
                         ay * dz - az * dy, az * dx - ax * dz, ax * dy - ay * dx])

    # -- equations of motion ---------------------------------------------
    def relative_velocity(self, state: np.ndarray, current_ned) -> np.ndarray:
        """Body velocities relative to the water: u, v, w minus the current in body axes."""
        nu_r = state[6:].copy()
        if current_ned is not None:
            r = rotation_body_to_ned(*state[3:6])
            nu_r[:3] -= r.T @ np.asarray(current_ned, float)
        return nu_r

    def input_derivatives(self, state, inputs, current_ned=None, external=None,
                          thrusters_on: bool = True) -> np.ndarray:
        """State derivative (12,) with the four ``inputs`` held long enough for the actuators to have
        reached them (:attr:`inputs`: the Seapup's blade pitches themselves; a virtual-input vehicle's
        thrusters at the mixer's commands): the function trims and linearisations are taken of."""
        return self.derivatives(state, self.inputs.to_actuators(np.asarray(inputs, float)), current_ned, external,
                                thrusters_on)

    def derivatives(self, state, pitch, current_ned=None, external=None,
                    thrusters_on: bool = True) -> np.ndarray:
        """State derivative (12,) for the actuators' present settings ``pitch`` (eq. 2.1-2.3).

        Parameters
        ----------
        state : array (12,)
        pitch : array (N,)
            What the thrusters actually apply: the Seapup's four blade pitches [rad], or each fixed-pitch
            thruster's (lagged) command in [-1, 1].
        current_ned : array (3,), optional
            Water velocity in the NED frame [m/s] (horizontal in practice).
        external : array (6,), optional
            External wrench in body axes (e.g. umbilical, eq. 2.3's U).
        thrusters_on : bool
            False removes the thrusters entirely (Table 3.2 tests 1-2: zero
            pitch would not, since thrust is not zero at zero pitch).
        """
        state = np.asarray(state, float)
        phi, theta = state[3], state[4]
        nu = state[6:]
        rot = rotation_body_to_ned(phi, theta, state[5])
        nu_r = nu.copy()
        if current_ned is not None:
            nu_r[:3] -= rot.T @ np.asarray(current_ned, float)
        # rot[2] is the NED down axis in body coordinates
        tau = (self.rigid_coriolis(nu) + self.added_mass_coriolis(nu_r) + self.hydro.forces(nu_r)
               + self._hydrostatics_from(rot[2]))
        if thrusters_on:
            tau += self.thrusters.wrench(nu_r, np.asarray(pitch, float))
        if external is not None:
            tau += external
        out = np.empty(12)
        out[:3] = rot @ nu[:3]
        out[3:6] = euler_rate_matrix(phi, theta) @ nu[3:]
        out[6:] = self.m_inv @ tau
        return out
