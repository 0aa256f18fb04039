"""Identification of the linearised Seapup (thesis sec. 6.5.1; issue 14 deliverable 4).

Truth: the linear model of eq. 3.2 about hover (seapup_sim.analysis.linearise), discretised
behind a zero-order hold at 5 Hz (scipy.signal.cont2discrete). With all eight dynamic states as
outputs (roll, pitch, u, v, w, p, q, r) its exact ARX representation is first order,
y(t) = Phi y(t-1) + Delta u(t-1), i.e. A_1 = -Phi and B_1 = Delta, which least squares must
recover from noise-free PRBS data. With the thesis's six outputs (u, v, w, r, roll, pitch; p and
q unmeasured) a second-order ARX predicts the noise-free data exactly and a first-order one cannot.
"""
import numpy as np
import pytest
import scipy.signal

from seapup_ident.armax import ArmaxOrders
from seapup_ident.identify import IdentificationData, fit
from seapup_ident.prbs import prbs
from seapup_sim.analysis import hover_blade_pitch, linearise
from seapup_sim.vehicle import VehicleModel
from seapup_sim.vehicle_config import load_vehicle_config

pytestmark = pytest.mark.unit

DYNAMIC = [3, 4, 6, 7, 8, 9, 10, 11]   # roll, pitch, u, v, w, p, q, r in the 12-state vector
SIX = [6, 7, 8, 11, 3, 4]              # u, v, w, r, roll, pitch (ch. 6's outputs)


@pytest.fixture(scope="module")
def linear_seapup():
    model = VehicleModel(load_vehicle_config("baseline"))
    hover = hover_blade_pitch(model)
    state = np.zeros(12)
    state[2] = 50.0
    a, b = linearise(model, state, hover)
    others = [i for i in range(12) if i not in DYNAMIC]
    assert np.abs(a[np.ix_(DYNAMIC, others)]).max() < 1e-6   # position and heading do not feed back
    phi, delta, *_ = scipy.signal.cont2discrete((a[np.ix_(DYNAMIC, DYNAMIC)], b[DYNAMIC], np.eye(8),
                                                 np.zeros((8, 4))), 0.2, method="zoh")
    u = prbs(1500, clock=10, amplitude=np.radians(10), n_inputs=4, nbits=8)
    x = np.zeros((1500, 8))
    for t in range(1, 1500):
        x[t] = phi @ x[t - 1] + delta @ u[t - 1]
    return phi, delta, x, u


def test_all_dynamic_states_as_outputs_give_back_phi_and_delta(linear_seapup):
    phi, delta, x, u = linear_seapup
    result = fit(IdentificationData(x, u), ArmaxOrders(8, 4, 1, 1, 0, offset=False), "ls", p0=1e6,
                 forgetting=None, passes=2)
    np.testing.assert_allclose(-result.model.A[0], phi, atol=1e-6)
    np.testing.assert_allclose(result.model.B[0], delta, atol=1e-6)


def test_the_six_thesis_outputs_need_second_order(linear_seapup):
    _, _, x, u = linear_seapup
    index = [DYNAMIC.index(i) for i in SIX]
    data = IdentificationData(x[:, index], u, outputs=("u", "v", "w", "r", "roll", "pitch"))
    first = fit(data, ArmaxOrders(6, 4, 1, 1, 0, offset=False), "ls", p0=1e6, passes=3)
    second = fit(data, ArmaxOrders(6, 4, 2, 2, 0, offset=False), "ls", p0=1e6, passes=3)
    scale = np.var(data.y, axis=0)
    assert np.all(second.loss / scale < 1e-9)                 # exact: p and q reconstructed from two samples
    assert np.max(first.loss / scale) > 1e-4                  # first order misses them
