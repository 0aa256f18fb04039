"""Every docstring example in the packages runs and prints what it says (numpydoc Examples sections)."""
import doctest
import importlib
import pkgutil

import pytest

PACKAGES = ["seapup_common", "seapup_sim", "seapup_control", "seapup_ident", "seapup_bringup"]


def modules():
    for package in PACKAGES:
        root = importlib.import_module(package)
        for info in pkgutil.walk_packages(root.__path__, package + "."):
            yield info.name


@pytest.mark.parametrize("name", sorted(modules()))
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS,
                             extraglobs={"np": importlib.import_module("numpy")})
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"
