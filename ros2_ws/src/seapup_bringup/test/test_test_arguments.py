"""``./seapup test``'s pytest arguments (seapup_bringup.cli.pytest_arguments): a worker per CPU, whole files to a
worker, unless the arguments choose otherwise."""
import pytest

from seapup_bringup.cli import pytest_arguments


@pytest.mark.parametrize("argv, cpus, expected", [
    ([], 2, ["-n", "2", "--dist", "loadfile"]),
    (["-m", "unit"], 4, ["-n", "4", "--dist", "loadfile", "-m", "unit"]),
    (["-m", "unit"], 1, ["-m", "unit"]),                       # one CPU: no worker to spare
    (["-n", "3"], 2, ["-n", "3"]),                             # the caller's count
    (["-n3"], 2, ["-n3"]),
    (["--numprocesses=0"], 2, ["--numprocesses=0"]),
    (["-p", "no:xdist", "tests"], 2, ["-p", "no:xdist", "tests"]),
    (["--help"], 2, ["--help"]),
    (["-x", "tests/test_demo.py"], 2, ["-x", "tests/test_demo.py"]),
    (["--pdb"], 2, ["--pdb"]),
    (["tests/test_node_names.py"], 2, ["-n", "2", "--dist", "loadfile", "tests/test_node_names.py"]),
])
def test_workers_unless_the_arguments_choose(argv, cpus, expected):
    assert pytest_arguments(argv, cpus=cpus) == expected
