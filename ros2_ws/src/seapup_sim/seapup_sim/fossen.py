"""A Fossen-style paper's vehicle model integrated as the paper writes it: a reference, independent of the thesis's
general model (ch. 2: :class:`~seapup_sim.vehicle.VehicleModel`), for verifying a vehicle description written from
such a paper (``./seapup verify --config bluerov2_heavy``; docs/vehicles.md).

The BlueROV2 Heavy of von Benzon et al. 2022 ([vB], ``references/von_benzon_2022.yaml``) is Fossen's vectorial
model ([vB] eq. 1-15), in body axes (FRD, origin at the CG) and NED::

    M nu_dot + C_RB(nu) nu + C_A(nu) nu + D(nu) nu + g(eta) = tau,        eta_dot = J(eta) nu
    M     = diag(m, m, m, I_x, I_y, I_z) + diag(X_udot, Y_vdot, Z_wdot, K_pdot, M_qdot, N_rdot)
    C_RB  = [[0, -m S(nu_1)], [-m S(nu_1), -S(I nu_2)]]                    (r_g = 0)
    C_A   = [[0, -S(A_11 nu_1)], [-S(A_11 nu_1), -S(A_22 nu_2)]]            (diagonal added mass)
    D     = diag(X_u + X_u|u| |u|, ..., N_r + N_r|r| |r|)                    (positive magnitudes)
    g     = [(W - B) s_theta, -(W - B) c_theta s_phi, -(W - B) c_theta c_phi,
             -(y_g W - y_b B) c_theta c_phi + (z_g W - z_b B) c_theta s_phi,
              (z_g W - z_b B) s_theta + (x_g W - x_b B) c_theta c_phi,
             -(x_g W - x_b B) c_theta s_phi - (y_g W - y_b B) s_theta]
    tau   = sum_i [d_i; r_i x d_i] F_i,    F_i = K(s) f(c_i)                 (eq. 16-18)

with S(a) b = a x b, f the T200's static thrust polynomial and K(s) its third-order dynamics, each thruster at
the paper's rotations of two points. Nothing here is shared with the simulator but numpy and scipy's adaptive
integrator (``solve_ivp``, RK45 to 1e-9): the description, the general model's hydrodynamic terms and Kirchhoff
coupling, the mixer's thruster layout, the first-order lag and the fixed-step RK4 are what it checks.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["FossenReference", "load_reference", "reference_for", "available_references", "respond",
           "steady_speed", "verify_fossen", "REFERENCES_DIR"]

#: the shipped references (one YAML per paper)
REFERENCES_DIR = Path(__file__).resolve().parent / "references"


def _skew(a) -> np.ndarray:
    """S(a): S(a) b = a x b."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


@dataclass(frozen=True)
class FossenReference:
    """A paper's model: the parameters of the module docstring's equations (SI, the paper's conventions)."""

    name: str
    vehicle: str                 # the shipped description it verifies
    mass: float
    inertia: np.ndarray          # (3,) I_x, I_y, I_z
    added_mass: np.ndarray       # (6,) magnitudes
    linear_damping: np.ndarray   # (6,)
    quadratic_damping: np.ndarray
    weight: float                # W = m g [N]
    buoyancy: float              # B = rho g V [N]
    r_g: np.ndarray
    r_b: np.ndarray
    thrust_matrix: np.ndarray    # (6, N): [d_i; r_i x d_i]
    thrust_polynomial: np.ndarray
    numerator: np.ndarray        # K(s)
    denominator: np.ndarray

    @property
    def inertia_matrix(self) -> np.ndarray:
        """M = M_RB + M_A (6, 6)."""
        return np.diag(np.r_[self.mass, self.mass, self.mass, self.inertia] + self.added_mass)

    def static_thrust(self, command) -> np.ndarray:
        """f(c) [N] of each command (eq. 18), the command taken within [-1, 1]."""
        return np.polynomial.polynomial.polyval(np.clip(np.asarray(command, float), -1.0, 1.0),
                                                self.thrust_polynomial)

    def wrench(self, thrust) -> np.ndarray:
        """tau (6,) of the thrusters' forces [N]."""
        return self.thrust_matrix @ np.asarray(thrust, float)

    def derivatives(self, state: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """d/dt of the state (x, y, z, phi, theta, psi, u, v, w, p, q, r) under the generalised force ``tau``."""
        phi, theta, psi = state[3:6]
        nu = state[6:12]
        nu1, nu2 = nu[:3], nu[3:]
        m = self.mass
        a11, a22 = np.diag(self.added_mass[:3]), np.diag(self.added_mass[3:])
        c_rb = np.block([[np.zeros((3, 3)), -m * _skew(nu1)], [-m * _skew(nu1), -_skew(self.inertia * nu2)]])
        c_a = np.block([[np.zeros((3, 3)), -_skew(a11 @ nu1)], [-_skew(a11 @ nu1), -_skew(a22 @ nu2)]])
        d = np.diag(self.linear_damping + self.quadratic_damping * np.abs(nu))
        (xg, yg, zg), (xb, yb, zb), w, b = self.r_g, self.r_b, self.weight, self.buoyancy
        sf, cf, st, ct = math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta)
        g = np.array([(w - b) * st, -(w - b) * ct * sf, -(w - b) * ct * cf,
                      -(yg * w - yb * b) * ct * cf + (zg * w - zb * b) * ct * sf,
                      (zg * w - zb * b) * st + (xg * w - xb * b) * ct * cf,
                      -(xg * w - xb * b) * ct * sf - (yg * w - yb * b) * st])
        nu_dot = np.linalg.solve(self.inertia_matrix, tau - c_rb @ nu - c_a @ nu - d @ nu - g)
        cp, sp = math.cos(psi), math.sin(psi)
        rotation = np.array([[cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st],
                             [sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf],
                             [-st, ct * sf, ct * cf]])
        euler = np.array([[1.0, sf * st / ct, cf * st / ct], [0.0, cf, -sf], [0.0, sf / ct, cf / ct]])
        return np.r_[rotation @ nu1, euler @ nu2, nu_dot]


def _thrust_matrix(groups) -> np.ndarray:
    columns = []
    for group in groups:
        point, direction = np.asarray(group["point"], float), np.asarray(group["direction"], float)
        for alpha, beta in zip(group["alpha"], group["beta"]):
            rz = lambda a: np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0],  # noqa: E731
                                     [0.0, 0.0, 1.0]])
            r, d = rz(float(alpha)) @ point, rz(float(beta)) @ direction
            columns.append(np.r_[d, np.cross(r, d)])
    return np.array(columns).T


def available_references() -> list[str]:
    """The shipped references' names."""
    return sorted(p.stem for p in REFERENCES_DIR.glob("*.yaml"))


def load_reference(name: str) -> FossenReference:
    """A shipped reference by name (``references/<name>.yaml``; strict keys, finite numbers)."""
    from seapup_common.config import ConfigError, parsed_yaml
    if name not in available_references():
        raise ConfigError(f"no reference model {str(name)[:80]!r} (shipped: {', '.join(available_references())})")
    path = REFERENCES_DIR / f"{name}.yaml"
    data = parsed_yaml(path)
    keys = {"name", "vehicle", "rho", "g", "mass", "volume", "r_g", "r_b", "inertia", "added_mass", "linear_damping",
            "quadratic_damping", "thrust_polynomial", "thruster_dynamics", "thrusters"}
    if set(data) != keys:
        raise ConfigError(f"{path}: keys {sorted(set(data) ^ keys)} missing or unknown")

    def vector(key, n=None):
        value = np.asarray(data[key], float)
        if value.ndim != 1 or (n is not None and value.size != n) or not np.all(np.isfinite(value)):
            raise ConfigError(f"{path}: {key} needs {n or 'a list of'} finite numbers")
        return value
    g, rho = float(data["g"]), float(data["rho"])
    if np.any(vector("r_g", 3) != 0.0):
        raise ConfigError(f"{path}: r_g must be the body origin (0, 0, 0): C_RB is written for it")
    return FossenReference(
        str(data["name"]), str(data["vehicle"]), float(data["mass"]), vector("inertia", 3), vector("added_mass", 6),
        vector("linear_damping", 6), vector("quadratic_damping", 6), float(data["mass"]) * g,
        rho * g * float(data["volume"]), vector("r_g", 3), vector("r_b", 3), _thrust_matrix(data["thrusters"]),
        vector("thrust_polynomial"), np.asarray(data["thruster_dynamics"]["numerator"], float),
        np.asarray(data["thruster_dynamics"]["denominator"], float))


def reference_for(vehicle: str) -> FossenReference | None:
    """The shipped reference that verifies description ``vehicle`` (its ``vehicle``), or None."""
    for name in available_references():
        reference = load_reference(name)
        if reference.vehicle == vehicle:
            return reference
    return None


def respond(reference: FossenReference, commands, t, state0=None) -> np.ndarray:
    """The paper's model from ``state0`` (default rest) with the thrusters' commands ``commands`` (N,) held from
    t = 0 (each thrust through K(s) from zero): the states (len(t), 12) at the times ``t``."""
    from scipy.integrate import solve_ivp
    from scipy.signal import tf2ss
    a, b, c, d = tf2ss(reference.numerator, reference.denominator)
    static = reference.static_thrust(commands)
    n, order = static.size, a.shape[0]

    def rhs(_, y):
        state, lag = y[:12], y[12:].reshape(n, order)
        thrust = lag @ c[0] + d[0, 0] * static
        lag_dot = lag @ a.T + np.outer(static, b[:, 0])
        return np.r_[reference.derivatives(state, reference.wrench(thrust)), lag_dot.ravel()]
    y0 = np.r_[np.zeros(12) if state0 is None else np.asarray(state0, float), np.zeros(n * order)]
    t = np.asarray(t, float)
    solution = solve_ivp(rhs, (0.0, float(t[-1])), y0, t_eval=t, rtol=1e-9, atol=1e-11)
    if not solution.success:
        raise RuntimeError(f"the reference model's integration failed: {solution.message}")
    return solution.y[:12].T


def steady_speed(linear: float, quadratic: float, force: float) -> float:
    """The speed at which linear and quadratic damping balance ``force``: (d1 + d2 |x|) x = F."""
    if quadratic == 0.0:
        return force / linear
    return math.copysign((-linear + math.sqrt(linear * linear + 4.0 * quadratic * abs(force))) / (2.0 * quadratic),
                         force)


#: The open-loop responses compared: (name, the virtual inputs held, the output's state index, unit)
#: (surge at 0.3 of full scale: 0.38 m/s, below the heave-pitch instability of [vB]'s model from about 0.45 m/s,
#: which swings full surge through 65-81 deg of pitch in the two models; sway, heave and yaw at full scale)
RESPONSES = (("surge ahead", (0.3, 0.0, 0.0, 0.0), 6, "m/s"), ("sway to starboard", (0.0, 1.0, 0.0, 0.0), 7, "m/s"),
             ("heave down", (0.0, 0.0, 1.0, 0.0), 8, "m/s"), ("heave up", (0.0, 0.0, -1.0, 0.0), 8, "m/s"),
             ("yaw to starboard", (0.0, 0.0, 0.0, 1.0), 11, "rad/s"))
#: [fraction] a steady speed's agreement asked of the description flown by the general model (the layouts differ by
#: 0.6 mm, the integrators by RK4's 0.1 s step against RK45 to 1e-9): the physics is the same equations
STEADY_TOLERANCE = 0.01
#: [s] the 90 % rise times' agreement asked (the first-order lag against K(s); a sample is 0.1 s)
RISE_TOLERANCE = 0.1


def _rise(t, y, fraction=0.9) -> float:
    final = y[-1]
    above = np.flatnonzero(np.abs(y) >= fraction * abs(final))
    return float(t[above[0]]) if above.size else math.nan


def verify_fossen(model, reference: FossenReference, duration: float = 30.0, dt: float = 0.1):
    """Each of :data:`RESPONSES` flown from rest by the description (``model``: its mixer's thruster commands for
    the inputs, its plant) and by the paper's model with the same thruster commands: their steady speeds and 90 %
    rise times (``ok`` within :data:`STEADY_TOLERANCE` / :data:`RISE_TOLERANCE`), the largest difference over
    the run, and the balance of damping and force on the one axis (:func:`steady_speed`, no integration: what a
    motion confined to its axis reaches -- heave and yaw are, by the frame's symmetry; a surge or sway also
    pitches or rolls the vehicle, the thrusters being below the CG). Returns (rows, time histories)."""
    from seapup_sim.integrator import VehicleIntegrator
    rows, hist = [], {}
    n = int(round(duration / dt))
    t = np.arange(n + 1) * dt
    for name, inputs, index, unit in RESPONSES:
        inputs = np.array(inputs, float)
        plant = VehicleIntegrator(model, dt=dt, pitch=np.zeros(4))
        ours = np.empty((n + 1, 12))
        ours[0] = plant.state
        for k in range(1, n + 1):
            ours[k] = plant.step(inputs)
        commands = np.asarray(model.inputs.to_actuators(inputs), float)
        theirs = respond(reference, commands, t)
        hist[name] = (t, ours, theirs)
        tau = reference.wrench(reference.static_thrust(commands))
        force = tau[index - 6] + ((reference.weight - reference.buoyancy) if index == 8 else 0.0)
        balance = steady_speed(reference.linear_damping[index - 6], reference.quadratic_damping[index - 6], force)
        settled = t >= duration - 2.0
        mine, paper = float(ours[settled, index].mean()), float(theirs[settled, index].mean())
        rise_mine, rise_paper = _rise(t, ours[:, index]), _rise(t, theirs[:, index])
        rows.append({"test": name, "unit": unit, "description": mine, "reference": paper, "balance": balance,
                     "rise_description_s": rise_mine, "rise_reference_s": rise_paper,
                     "largest_difference": float(np.abs(ours[:, index] - theirs[:, index]).max()),
                     "ok": bool(abs(mine - paper) <= STEADY_TOLERANCE * abs(paper)
                                and abs(rise_mine - rise_paper) <= RISE_TOLERANCE + 1e-9)})
    return rows, hist
