"""robotarium_bringup.domains: each ROS_DOMAIN_ID handed out is held by its process; when all are held, a
domain this process drew earlier comes back only where `reusable` says nothing runs on it any more."""
import os
import subprocess
import sys

import pytest

from robotarium_bringup import domains


@pytest.fixture
def three_domains(tmp_path, monkeypatch):
    monkeypatch.setattr(domains, "_DOMAIN_LOCKS", str(tmp_path))
    monkeypatch.setattr(domains, "_MAX_DOMAIN_ID", 3)
    monkeypatch.setattr(domains, "_held", {})
    monkeypatch.setattr(domains, "_cursor", [None])
    monkeypatch.setattr(domains, "reusable", None)
    yield tmp_path
    for fd in domains._held.values():
        os.close(fd)


def test_every_domain_held_is_an_error_unless_an_earlier_one_is_reusable(three_domains):
    drawn = [domains.unique_domain_id() for _ in range(3)]
    assert sorted(drawn) == [1, 2, 3]
    with pytest.raises(RuntimeError, match="every ROS_DOMAIN_ID 1..3 is held"):
        domains.unique_domain_id()
    domains.reusable = lambda domain: domain != drawn[0]   # the first still has a process on it
    assert domains.unique_domain_id() == drawn[1]            # the earliest drawn of the others
    assert domains.unique_domain_id() == drawn[2]
    assert domains.unique_domain_id() == drawn[1]            # (each comes back as the newest drawn)


def test_a_domain_another_process_holds_is_never_handed_out(three_domains):
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time\n"
                               "fd = os.open(sys.argv[1], os.O_CREAT | os.O_RDWR)\n"
                               "fcntl.flock(fd, fcntl.LOCK_EX)\nprint('held', flush=True)\ntime.sleep(60)\n",
                               str(three_domains / "2.lock")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        domains.reusable = lambda domain: True
        assert sorted(domains.unique_domain_id() for _ in range(2)) == [1, 3]
        assert domains.unique_domain_id() in (1, 3)   # its own again, never the other process's 2
    finally:
        holder.kill()
        holder.wait()
