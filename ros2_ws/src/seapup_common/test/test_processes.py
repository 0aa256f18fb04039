"""Tests of seapup_common.processes: domain leases and child processes."""
import subprocess
import sys
import textwrap

import pytest

from seapup_common.processes import (DomainLease, NodeProcess, NoFreeDomainError,
                                       find_executable, ros_environment)

HOLD_LEASE = textwrap.dedent("""
    import sys, time
    from seapup_common.processes import DomainLease
    lease = DomainLease(sys.argv[1], candidates=[int(x) for x in sys.argv[2:]])
    print(lease.acquire(), flush=True)
    time.sleep(60)
""")


def test_two_leases_in_one_process_get_different_domains(tmp_path):
    with DomainLease(tmp_path, candidates=[40, 41]) as a, DomainLease(tmp_path, candidates=[40, 41]) as b:
        assert {a.domain_id, b.domain_id} == {40, 41}
        with pytest.raises(NoFreeDomainError, match="40-41"):
            DomainLease(tmp_path, candidates=[40, 41]).acquire()


@pytest.mark.process
def test_lease_is_exclusive_across_processes_and_freed_when_holder_dies(tmp_path):
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LEASE, str(tmp_path), "50"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "50"
        with pytest.raises(NoFreeDomainError):
            DomainLease(tmp_path, candidates=[50]).acquire()
    finally:
        holder.kill()
        holder.wait()
    with DomainLease(tmp_path, candidates=[50]) as lease:  # the kernel dropped the lock
        assert lease.domain_id == 50


def test_release_is_idempotent_and_allows_reacquire(tmp_path):
    lease = DomainLease(tmp_path, candidates=[60])
    assert lease.acquire() == 60
    lease.release()
    lease.release()
    assert DomainLease(tmp_path, candidates=[60]).acquire() == 60


def test_a_released_domain_is_the_last_one_taken_again(tmp_path):
    """Least recently used first: a domain just given back is not handed to the next lease while
    others are free (a slow-to-die process of its last holder would be heard there)."""
    taken = []
    for _ in range(4):
        with DomainLease(tmp_path, candidates=[70, 71, 72]) as lease:
            taken.append(lease.domain_id)
    assert sorted(taken[:3]) == [70, 71, 72] and taken[3] == taken[0]
    with DomainLease(tmp_path, candidates=[70, 71, 72]) as held:   # a held domain is skipped, used or not
        with DomainLease(tmp_path, candidates=[70, 71, 72]) as other:
            assert other.domain_id != held.domain_id


def test_ros_environment_is_loopback_only():
    env = ros_environment(17, {"ROS_STATIC_PEERS": "10.0.0.1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"})
    assert env["ROS_DOMAIN_ID"] == "17"
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert "ROS_STATIC_PEERS" not in env
    with pytest.raises(ValueError):
        ros_environment(233)


@pytest.mark.process
def test_stop_escalates_when_sigint_is_ignored(tmp_path):
    stubborn = "import signal, time\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\nprint('up', flush=True)\ntime.sleep(60)"
    proc = NodeProcess([sys.executable, "-c", stubborn], {}, tmp_path / "p.log").start()
    for _ in range(200):
        if "up" in proc.log_text():
            break
        import time
        time.sleep(0.02)
    assert proc.running
    code = proc.stop(grace=0.3)
    assert code == -15  # SIGINT ignored, SIGTERM ended it
    assert not proc.running


def test_find_executable_reports_what_is_missing():
    assert find_executable("seapup_sim", "simulator").name == "simulator"
    with pytest.raises(FileNotFoundError, match="no executable 'nope'"):
        find_executable("seapup_sim", "nope")


@pytest.mark.process
def test_a_hurried_stop_sends_sigterm_first(tmp_path):
    """``hurry`` (the owner was interrupted): the group gets SIGTERM at once, never the SIGINT grace first."""
    import signal
    from seapup_common.processes import stop_process_groups
    record = tmp_path / "signals"
    probe = ("import signal, sys, time\n"
             f"def note(s, f):\n    open({str(record)!r}, 'a').write(f'{{s}}\\n')\n    sys.exit(0)\n"
             "signal.signal(signal.SIGINT, note)\nsignal.signal(signal.SIGTERM, note)\n"
             "print('up', flush=True)\ntime.sleep(60)")
    popen = subprocess.Popen([sys.executable, "-c", probe], stdout=subprocess.PIPE, text=True, start_new_session=True)
    assert popen.stdout.readline() == "up\n"
    stop_process_groups([popen], grace=30.0, term_grace=30.0, hurry=True)
    assert popen.wait(5) == 0 and record.read_text().split() == [str(int(signal.SIGTERM))]
