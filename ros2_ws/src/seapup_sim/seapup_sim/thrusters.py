"""Fixed-speed, controllable-pitch ducted thrusters of the Seapup.

Four thrusters (thesis sec. 2.3.3, 3.1): two main thrusters aft, port and
starboard, along the body x axis; two vectored thrusters on the centreline at
45 deg to the vertical, which push together for heave and push-pull for sway.

Each thruster turns at a fixed shaft speed n [rev/s]; its axial thrust is

    T = rho n^2 D^4 K_T(J, beta),   J = V_a / (n D)          (eq. 2.18)

with the advance coefficient J from the axial inflow V_a, and a thrust
coefficient linear in blade pitch beta and advance coefficient, which has the
shape of the thesis's fig. 2.2 (thrust falls with J, and is not zero at zero
pitch):

    K_T(J, beta) = k_beta (beta - beta_0) - k_J J

beta_0 is the pitch of zero bollard thrust (-3.383 deg: the main thrusters'
hover setting, eq. 5.2). A thruster moved normal to its axis suffers momentum
drag (Dand and Every, eq. 2.19)

    R = (pi/2) rho n D^3 V_n sqrt(K_0 / pi)

opposing the normal velocity V_n, with K_0 = |K_T(0, beta)|. sqrt(K_0) has an
infinite slope at zero thrust, which stalls trim solvers and makes the
linearisation (eq. 3.3) meaningless there; |K_T| is therefore taken smoothly as
sqrt(K_T^2 + eps^2) with eps = ``momentum_drag_epsilon`` (default 0.005, about
3 % of the full-pitch thrust coefficient), which changes the drag only near
zero thrust.

The thrusts act on the vehicle through the open-water matrix G, scaled element
by element by a 6x4 matrix of dimensionless *installation coefficients* c
(thesis sec. 3.5: "most ... between zero and one, reflecting the fact that the
thruster unit contributes less force when installed than in open water")::

    tau = (c * G) T,   G[:, j] = [d_j ; r_j x d_j + s_j (K_Q/K_T) D d_j]

Column j of G is the open-water force and moment of a unit thrust at position
r_j along axis d_j, including the propeller's torque reaction (rotation sense
s_j = +/-1, torque-to-thrust ratio K_Q/K_T): it is the main thrusters' only
open-water roll moment. The thesis's calibrated roll coefficients (0.22 main,
0.34 vectored) and the vectored thrusters' yaw coefficient (0.15 of open
water) are entries of c. A fouled thruster is modelled by an efficiency factor
scaling its column (sec. 7.4.4).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ThrusterSet", "ThrustCurve", "FixedPitchThrusters", "check_efficiency", "THRUSTER_KINDS"]

#: The kinds of thruster a vehicle description may have (``thrusters.kind``).
THRUSTER_KINDS = ("controllable_pitch", "fixed_pitch")



def check_efficiency(efficiency, count: int = 4) -> np.ndarray:
    """``count`` thruster efficiencies as a new array: finite factors in [0, 1.5] (ValueError otherwise)."""
    eff = np.array(efficiency, dtype=float)
    if eff.shape != (count,) or not np.all(np.isfinite(eff)) or np.any(eff < 0) or np.any(eff > 1.5):
        shown = ", ".join(f"{float(x):g}" for x in eff.ravel()[:8]) if eff.size else str(efficiency)[:80]
        raise ValueError(f"thruster efficiency needs {count} finite factors in [0, 1.5], got [{shown}]")
    return eff


@dataclass
class ThrusterSet:
    """The four thrusters as one vectorised actuator.

    Parameters
    ----------
    rho : float
        Water density [kg/m^3].
    shaft_speed : float
        n [rev/s], fixed.
    diameter : float
        D [m].
    k_beta : float
        dK_T/d(beta) [1/rad].
    k_j : float
        -dK_T/dJ [-].
    zero_thrust_pitch : float
        beta_0 [rad].
    positions : array (4, 3)
        Thruster centres in body axes [m] (FRD, from the body origin).
    directions : array (4, 3)
        Unit thrust axes in body axes (positive pitch pushes the water
        backwards along -d, so the vehicle is pushed along +d).
    installation : array (6, 4)
        Installation coefficients c (dimensionless multipliers of G).
    rotation : array (4,)
        Propeller rotation sense s_j (+1 or -1) for the torque reaction.
    torque_ratio : float
        K_Q / K_T of the propeller [-].
    momentum_drag_factor : float
        Scales eq. 2.19 (1.0 = Dand and Every).
    momentum_drag_epsilon : float
        Smoothing of |K_0| near zero thrust (see module docstring).
    """

    rho: float
    shaft_speed: float
    diameter: float
    k_beta: float
    k_j: float
    zero_thrust_pitch: float
    positions: np.ndarray
    directions: np.ndarray
    installation: np.ndarray
    rotation: np.ndarray = (1.0, -1.0, 1.0, -1.0)
    kind = "controllable_pitch"
    count = 4
    torque_ratio: float = 0.0
    momentum_drag_factor: float = 1.0
    momentum_drag_epsilon: float = 0.005

    def __post_init__(self):
        self.positions = np.asarray(self.positions, float).reshape(4, 3)
        d = np.asarray(self.directions, float).reshape(4, 3)
        self.directions = d / np.linalg.norm(d, axis=1, keepdims=True)
        self.installation = np.asarray(self.installation, float).reshape(6, 4)
        self.rotation = np.asarray(self.rotation, float).reshape(4)
        self.open_water = self.open_water_matrix()
        #: the installed matrix c * G [N/N, N m/N]
        self.matrix = self.installation * self.open_water
        self.efficiency = np.ones(4)
        # Precomputed maps (hot path): velocity of each thruster centre is
        # v + w x r_j = [I, -S(r_j)] nu; the wrench of forces f_j at r_j is
        # [sum f_j ; sum S(r_j) f_j].
        s_r = np.array([[[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]]
                        for r in self.positions])
        self._point_map = np.vstack([np.hstack([np.eye(3), -s_r[j]]) for j in range(4)])  # (12, 6)
        self._force_map = np.vstack([np.hstack([np.eye(3)] * 4), np.hstack(list(s_r))])   # (6, 12)
        self._thrust_scale = self.rho * self.shaft_speed ** 2 * self.diameter ** 4
        self._md_scale = (0.5 * np.pi * self.rho * self.shaft_speed * self.diameter ** 3
                          * self.momentum_drag_factor)

    def open_water_matrix(self) -> np.ndarray:
        """G (6, 4): open-water force and moment per newton of each thrust."""
        g = np.zeros((6, 4))
        g[:3] = self.directions.T
        torque = (self.rotation * self.torque_ratio * self.diameter)[:, None] * self.directions
        g[3:] = (np.cross(self.positions, self.directions) + torque).T
        return g

    def set_efficiency(self, efficiency) -> None:
        """Per-thruster factors in [0, 1.5] on the installation coefficients (fouling,
        sec. 7.4.4: the main port thruster's coefficients halved). Momentum drag is
        a property of the rotating propeller and is not scaled."""
        self.efficiency = check_efficiency(efficiency)

    def thrust_coefficient(self, advance: np.ndarray, pitch: np.ndarray) -> np.ndarray:
        """K_T(J, beta) for each thruster."""
        return self.k_beta * (pitch - self.zero_thrust_pitch) - self.k_j * advance

    def point_velocities(self, nu_r: np.ndarray) -> np.ndarray:
        """Velocity of each thruster through the water, body axes (4, 3)."""
        return (self._point_map @ nu_r).reshape(4, 3)

    def thrust(self, nu_r: np.ndarray, pitch: np.ndarray) -> np.ndarray:
        """Axial thrust of each thruster [N] (before installation effects)."""
        v_axial = (self.point_velocities(nu_r) * self.directions).sum(axis=1)
        advance = v_axial / (self.shaft_speed * self.diameter)
        return self._thrust_scale * self.thrust_coefficient(advance, pitch)

    def wrench(self, nu_r: np.ndarray, pitch: np.ndarray) -> np.ndarray:
        """Forces and moments (6,) of all four thrusters on the vehicle."""
        vel = self.point_velocities(nu_r)
        dirs = self.directions
        v_axial = (vel * dirs).sum(axis=1)
        bollard = self.k_beta * (pitch - self.zero_thrust_pitch)
        thrust = self._thrust_scale * (bollard - self.k_j / (self.shaft_speed * self.diameter) * v_axial)
        tau = self.matrix @ (self.efficiency * thrust)
        # momentum drag (eq. 2.19), applied at each thruster centre
        k0 = np.sqrt(bollard * bollard + self.momentum_drag_epsilon ** 2)
        drag = (-self._md_scale * np.sqrt(k0 / np.pi))[:, None] * (vel - v_axial[:, None] * dirs)
        return tau + self._force_map @ drag.ravel()

    def bollard_thrust(self, pitch) -> np.ndarray:
        """Thrust at J = 0 [N] for blade pitches ``pitch`` [rad]."""
        return self._thrust_scale * self.thrust_coefficient(0.0, np.asarray(pitch, float))


class ThrustCurve:
    """Static thrust [N] of a fixed-pitch propeller thruster against its normalised command c in [-1, 1].

    Given as a polynomial in c (``coefficients`` of c^0, c^1, ...: a published fit, e.g. eq. 18 of von Benzon
    et al. 2022 for the T200) or as a table of (command, thrust) points, piecewise linear between them (a
    maker's bollard data: any asymmetry of forward and reverse thrust). A ``deadband`` d (a fraction of the
    command range) gives no thrust for |c| <= d and maps the rest of the range onto the curve,
    ``T(c) = curve(sign(c) (|c| - d) / (1 - d))`` -- an ESC that ignores small commands, with no jump in
    thrust at the band's edge. The curve must be zero at c = 0 and increasing over [-1, 1] (checked on a
    fine grid), so each thrust in [T(-1), T(1)] has one command: :meth:`command_for`.
    """

    GRID = 2001   # points of the checks and of the inverse's table

    def __init__(self, polynomial=None, table=None, deadband: float = 0.0):
        if (polynomial is None) == (table is None):
            raise ValueError("a thrust curve is a polynomial or a table, exactly one of them")
        if not (np.isfinite(deadband) and 0.0 <= deadband < 0.5):
            raise ValueError(f"the deadband must be in [0, 0.5) of the command range, got {deadband!r}")
        self.deadband = float(deadband)
        if polynomial is not None:
            coefficients = np.array(polynomial, dtype=float)
            if coefficients.ndim != 1 or not 1 <= coefficients.size <= 16 or not np.all(np.isfinite(coefficients)):
                raise ValueError("a thrust polynomial needs 1 to 16 finite coefficients (c^0 first)")
            self.coefficients, self.table = coefficients, None
        else:
            points = np.array(table, dtype=float)
            if points.ndim != 2 or points.shape[1] != 2 or not 3 <= len(points) <= 1000 \
                    or not np.all(np.isfinite(points)):
                raise ValueError("a thrust table needs 3 to 1000 finite (command, thrust [N]) pairs")
            if not (np.all(np.diff(points[:, 0]) > 0) and points[0, 0] == -1.0 and points[-1, 0] == 1.0):
                raise ValueError("a thrust table's commands must increase from -1 to 1")
            self.coefficients, self.table = None, points
        grid = np.linspace(-1.0, 1.0, self.GRID)
        thrust = self._curve(grid)
        if abs(float(self._curve(np.zeros(1))[0])) > 1e-9:
            raise ValueError("a thrust curve must give no thrust at zero command")
        # a fit may droop just short of full command (eq. 18 does, by 0.7 %): the curve is taken as the most
        # thrust either way that a command of at most that size gives (a running extreme outward from zero)
        middle = self.GRID // 2
        monotone = thrust.copy()
        monotone[middle:] = np.maximum.accumulate(thrust[middle:])
        monotone[:middle + 1] = np.minimum.accumulate(thrust[:middle + 1][::-1])[::-1]
        drop = float(np.max(np.abs(monotone - thrust)))
        if drop > 0.01 * float(np.abs(thrust).max()) or np.any(np.diff(monotone) < 0.0):
            raise ValueError(f"a thrust curve must increase with the command (it turns back by {drop:.3g} N)")
        self._grid = grid
        self._monotone = monotone
        self._droops = bool(drop > 0.0)   # then thrust() reads the monotone curve
        self.max_forward, self.max_reverse = float(self._monotone[-1]), float(self._monotone[0])
        if not (self.max_forward > 0.0 > self.max_reverse):
            raise ValueError("a thrust curve must push both ways: positive thrust at c = 1, negative at c = -1")

    def _curve(self, c: np.ndarray) -> np.ndarray:
        if self.table is not None:
            return np.interp(c, self.table[:, 0], self.table[:, 1])
        return np.polynomial.polynomial.polyval(c, self.coefficients)

    def thrust(self, command) -> np.ndarray:
        """T(c) [N] of each command (array), the deadband applied; commands beyond +-1 are taken at +-1."""
        c = np.clip(np.asarray(command, dtype=float), -1.0, 1.0)
        d = self.deadband
        if d > 0.0:
            c = np.sign(c) * np.maximum(np.abs(c) - d, 0.0) / (1.0 - d)
        return np.interp(c, self._grid, self._monotone) if self._droops else self._curve(c)

    def command_for(self, thrust) -> np.ndarray:
        """The command of each thrust [N] (array), clipped to what the curve can give; the inverse of
        :meth:`thrust` (the deadband's edge for the smallest thrusts either way; no thrust is no command, also
        where a table is flat about zero, as a maker's data are over an ESC's own band)."""
        t = np.clip(np.asarray(thrust, dtype=float), self.max_reverse, self.max_forward)
        c = np.interp(t, self._monotone, self._grid)
        d = self.deadband
        if d > 0.0:
            c = np.sign(c) * (d + np.abs(c) * (1.0 - d))
        return np.where(t == 0.0, 0.0, c)


@dataclass
class FixedPitchThrusters:
    """N fixed-pitch propeller thrusters (a BlueROV2's T200s): thrust from a static curve of each one's
    normalised command, along its axis at its position.

    The command c in [-1, 1] (an ESC's normalised pulse width) reaches the propeller through the vehicle's
    first-order actuator lag (:class:`seapup_sim.integrator.VehicleIntegrator`, ``actuator_time_constant``:
    the motor and propeller spinning up); the thrust of the lagged command is :class:`ThrustCurve`'s, scaled
    by the thruster's efficiency (fouling), and acts through ``tau = B (eff * T)``, ``B[:, i] = [d_i ;
    r_i x d_i]``. The thrust does not depend on the advance speed and the propeller's torque reaction is
    not modelled (von Benzon et al. 2022's model, eq. 16-18); nor is momentum drag.

    Parameters
    ----------
    positions : array (N, 3)
        Thruster centres in body axes [m] (FRD, from the body origin).
    directions : array (N, 3)
        Thrust axes in body axes (normalised here): a positive command pushes the vehicle along +d.
    curve : ThrustCurve
        Thrust against command, the same for every thruster.
    """

    positions: np.ndarray
    directions: np.ndarray
    curve: ThrustCurve
    kind = "fixed_pitch"

    def __post_init__(self):
        positions = np.array(self.positions, dtype=float)
        directions = np.array(self.directions, dtype=float)
        if positions.ndim != 2 or positions.shape[1] != 3 or not 1 <= len(positions) <= 32 \
                or directions.shape != positions.shape:
            raise ValueError("fixed-pitch thrusters need 1 to 32 positions and as many directions, each (x, y, z)")
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(directions))):
            raise ValueError("thruster positions and directions must be finite")
        norms = np.linalg.norm(directions, axis=1)
        if np.any(norms < 1e-9):
            raise ValueError("every thruster direction must be a non-zero vector")
        self.positions, self.directions = positions, directions / norms[:, None]
        self.count = len(positions)
        self.matrix = np.vstack([self.directions.T, np.cross(self.positions, self.directions).T])   # (6, N)
        self.open_water = self.matrix
        self.efficiency = np.ones(self.count)

    def set_efficiency(self, efficiency) -> None:
        """Per-thruster factors in [0, 1.5] on the thrust (fouling, a weak thruster)."""
        self.efficiency = check_efficiency(efficiency, self.count)

    def thrust(self, command) -> np.ndarray:
        """Each thruster's thrust [N] at its (lagged) command, before the efficiency."""
        return self.curve.thrust(command)

    def wrench(self, nu_r: np.ndarray, command: np.ndarray) -> np.ndarray:
        """Forces and moments (6,) of all the thrusters on the vehicle (``nu_r`` unused: no advance-speed or
        momentum-drag effect in this model)."""
        return self.matrix @ (self.efficiency * self.curve.thrust(command))
