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

__all__ = ["ThrusterSet", "check_efficiency"]



def check_efficiency(efficiency) -> np.ndarray:
    """Four thruster efficiencies as a new array: finite factors in [0, 1.5] (ValueError otherwise)."""
    eff = np.array(efficiency, dtype=float)
    if eff.shape != (4,) or not np.all(np.isfinite(eff)) or np.any(eff < 0) or np.any(eff > 1.5):
        shown = ", ".join(f"{float(x):g}" for x in eff.ravel()[:8]) if eff.size else str(efficiency)[:80]
        raise ValueError(f"thruster efficiency needs 4 finite factors in [0, 1.5], got [{shown}]")
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
