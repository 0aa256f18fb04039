"""The lockstep pace (seapup_common.lockstep.pacing), with explicit wall times."""
import pytest

from seapup_common.lockstep import Pacer
from seapup_common.lockstep.pacing import Pacer as PacerFromModule


def test_the_pacer_is_importable_from_the_package_and_its_module():
    assert Pacer is PacerFromModule


def test_a_pacer_spaces_samples_at_the_rate_never_bursts_after_a_stall_and_restarts_on_a_new_rate():
    assert Pacer(0.0).delay(5.0, 100.0) == 0.0                    # unpaced: at once, always
    pacer = Pacer(2.0)                                          # twice real time
    assert pacer.delay(0.0, 10.0) == 0.0                        # the first sample sets the schedule
    assert pacer.delay(0.2, 10.0) == pytest.approx(0.1)         # 0.2 s simulated = 0.1 s wall
    assert pacer.delay(0.2, 10.1) == 0.0
    assert pacer.delay(1.0, 10.2) == pytest.approx(0.3)
    assert pacer.delay(1.2, 13.0) == 0.0                        # a stall of 2.4 s ...
    assert pacer.delay(1.4, 13.0) == pytest.approx(0.1)         # ... then the pace again from there, no burst
    pacer.rate = 1.0
    assert pacer.delay(2.0, 20.0) == 0.0 and pacer.delay(2.2, 20.0) == pytest.approx(0.2)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="pace"):
            Pacer(bad)
