"""Tests of seapup_common.random_streams: one reproducible stream per component."""
import numpy as np
import pytest
import scipy.stats

from seapup_common.random_streams import RandomStreams


def test_a_stream_depends_only_on_seed_and_name():
    a, b = RandomStreams(3), RandomStreams(3)
    a.generator("sensors.velocity").standard_normal(10_000)  # a lot of draws elsewhere...
    x = a.generator("current").standard_normal(5)
    y = b.generator("current").standard_normal(5)              # ...change nothing here
    np.testing.assert_array_equal(x, y)
    assert not np.array_equal(x, RandomStreams(4).generator("current").standard_normal(5))


def test_streams_are_the_seed_sequence_children_addressed_by_name():
    s = RandomStreams(9).sequence("current")
    assert s.entropy == 9 and s.spawn_key == (RandomStreams.key("current"),)
    ref = np.random.Generator(np.random.PCG64(np.random.SeedSequence(9, spawn_key=(RandomStreams.key("current"),))))
    np.testing.assert_array_equal(RandomStreams(9).generator("current").random(4), ref.random(4))


def test_different_names_are_statistically_independent():
    streams = RandomStreams(1)
    x = streams.generator("a").standard_normal(20_000)
    y = streams.generator("b").standard_normal(20_000)
    r, p = scipy.stats.pearsonr(x, y)
    assert abs(r) < 4 / np.sqrt(20_000) and p > 1e-4


@pytest.mark.parametrize("seed", [-1, 1.5, "7", None, True])
def test_bad_seeds_are_refused(seed):
    with pytest.raises(ValueError, match="seed must be an integer"):
        RandomStreams(seed)
