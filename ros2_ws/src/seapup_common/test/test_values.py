"""What counts as a number (seapup_common.values): the YAML/JSON readers' one rule, against YAML's own types."""
import math

import numpy as np
import pytest
import yaml

from seapup_common.values import finite_real, is_real


@pytest.mark.parametrize("text, expected", [
    ("0.2", 0.2), ("3", 3.0), ("-1.5e+3", -1500.0),
    ("'0.2'", None), ("true", None), (".inf", None), ("-.inf", None), (".nan", None), ("null", None),
    ("[1]", None), ("{a: 1}", None), ("1" + "0" * 400, None),
])
def test_yaml_scalars(text, expected):
    value = yaml.safe_load(text)
    assert finite_real(value) == expected
    assert is_real(value) == (type(value) in (int, float))


def test_numpy_scalars_are_numbers_and_numpy_bools_are_not():
    assert finite_real(np.float32(0.5)) == 0.5 and finite_real(np.int64(7)) == 7.0
    assert not is_real(np.bool_(True)) and finite_real(np.bool_(True)) is None
    assert finite_real(np.float64(math.nan)) is None
