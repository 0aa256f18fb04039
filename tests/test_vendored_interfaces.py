"""The vendored ROS interface packages (vendor/ros/) are the upstream definitions: same type hash."""
import importlib
import json
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_share_directory
from rosbags.typesys import Stores, get_typestore

ROOT = Path(__file__).resolve().parents[1]
VENDORED = sorted(p.name for p in (ROOT / "vendor" / "ros").iterdir() if (p / "package.xml").is_file())


def _messages(package: str) -> list[str]:
    return sorted(p.stem for p in (ROOT / "vendor" / "ros" / package / "msg").glob("*.msg"))


@pytest.mark.parametrize("package", VENDORED)
def test_each_vendored_message_has_the_type_hash_of_ros_2_jazzy(package):
    """rosbags' Jazzy type store (definitions taken from the ROS 2 Jazzy release) is the independent truth;
    the installed description (generated from the vendored .msg, or the system's where one exists) must agree,
    else a bag or a viewer would see another type."""
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    share = Path(get_package_share_directory(package))
    assert _messages(package)
    for name in _messages(package):
        described = json.loads((share / "msg" / f"{name}.json").read_text())
        ours = next(h["hash_string"] for h in described["type_hashes"] if h["type_name"] == f"{package}/msg/{name}")
        assert ours == jazzy.hash_rihs01(f"{package}/msg/{name}")
        assert importlib.import_module(f"{package}.msg")   # and it imports (its type support is built)
