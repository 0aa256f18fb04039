"""Tests of seapup_sim.seabed."""
import math

import pytest

from seapup_sim.seabed import Seabed


def test_flat_slope_and_polyline():
    assert Seabed("flat", 80.0)(123.0, -4.0) == 80.0
    slope = Seabed("slope", 50.0, gradient=0.1, direction=math.pi / 2)
    assert slope(0.0, 100.0) == pytest.approx(60.0)
    assert slope(100.0, 0.0) == pytest.approx(50.0)
    poly = Seabed("polyline", points=[[0.0, 40.0], [10.0, 50.0], [20.0, 45.0]])
    assert poly(5.0, 0.0) == pytest.approx(45.0)
    assert poly(15.0, 99.0) == pytest.approx(47.5)
    assert poly(-5.0, 0.0) == 40.0 and poly(50.0, 0.0) == 45.0


@pytest.mark.parametrize("kwargs", [{"kind": "cliff"}, {"kind": "polyline", "points": [[0, 1]]},
                                    {"kind": "polyline", "points": [[1, 1], [0, 2]]}, {"depth": math.inf}])
def test_bad_profiles(kwargs):
    with pytest.raises(ValueError):
        Seabed(**kwargs)
