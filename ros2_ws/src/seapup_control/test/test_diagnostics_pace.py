"""DiagnosticsPace: a status every ``every`` samples, in lockstep no more often than real time gives."""
from seapup_control.ros.diagnostics_pace import DiagnosticsPace


def _published(pace, rate, samples=200, every=5, period=0.2):
    """The samples after which a status is published when samples come ``rate`` x faster than real time."""
    return [n for n in range(1, samples + 1) if pace.due(n, every, now=n * period / rate)]


def test_on_a_timer_every_nth_sample_whatever_the_rate():
    assert _published(DiagnosticsPace(0.2, lockstep=False), rate=100.0) == list(range(5, 201, 5))


def test_in_lockstep_at_or_below_real_time_every_nth_sample():
    assert _published(DiagnosticsPace(0.2, lockstep=True), rate=1.0) == list(range(5, 201, 5))
    assert _published(DiagnosticsPace(0.2, lockstep=True), rate=0.5) == list(range(5, 201, 5))


def test_in_lockstep_fast_one_status_per_real_time_period():
    # 50x real time: one wall second (every x T) is 250 samples; the first status comes at once
    published = _published(DiagnosticsPace(0.2, lockstep=True), rate=50.0, samples=1000)
    assert published == [5, 255, 505, 755]
