"""The host's thread pool follows the CPUs the process may use, not the machine's count."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from pycinder.util import threads

cgroup_cpus = threads._cgroup_cpus

@pytest.fixture
def clean_env(monkeypatch):
    monkeypatch.delenv("PYCINDER_THREADS", raising=False)
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    monkeypatch.setattr(threads, "_cgroup_cpus", lambda: None)
    return monkeypatch


def test_affinity_mask_bounds_the_pool(clean_env):
    clean_env.setattr(os, "sched_getaffinity", lambda pid: {3}, raising=False)
    clean_env.setattr(os, "cpu_count", lambda: 64)
    assert threads.usable_cpus() == 1
    assert threads.workers() == 1
    clean_env.setattr(os, "sched_getaffinity", lambda pid: set(range(20)), raising=False)
    assert threads.workers() == threads.MOST_WORKERS


def test_cgroup_quota_bounds_the_pool(clean_env, tmp_path):
    clean_env.setattr(os, "sched_getaffinity", lambda pid: set(range(16)), raising=False)
    (tmp_path / "cpu.max").write_text("250000 100000\n")
    assert cgroup_cpus(str(tmp_path)) == 2.5
    clean_env.setattr(threads, "_cgroup_cpus", lambda: 2.5)
    assert threads.usable_cpus() == 2
    clean_env.setattr(threads, "_cgroup_cpus", lambda: 0.5)  # half a CPU: one thread
    assert threads.usable_cpus() == 1
    # No quota (v2 "max"), and cgroup v1's files.
    (tmp_path / "cpu.max").write_text("max 100000\n")
    assert cgroup_cpus(str(tmp_path)) is None
    (tmp_path / "cpu.max").unlink()
    (tmp_path / "cpu").mkdir()
    (tmp_path / "cpu" / "cpu.cfs_quota_us").write_text("300000\n")
    (tmp_path / "cpu" / "cpu.cfs_period_us").write_text("100000\n")
    assert cgroup_cpus(str(tmp_path)) == 3.0
    (tmp_path / "cpu" / "cpu.cfs_quota_us").write_text("-1\n")
    assert cgroup_cpus(str(tmp_path)) is None
    assert cgroup_cpus(str(tmp_path / "absent")) is None


def test_environment_sets_or_caps_the_pool(clean_env):
    clean_env.setattr(os, "sched_getaffinity", lambda pid: set(range(16)), raising=False)
    clean_env.setenv("OMP_NUM_THREADS", "3,2")  # OpenMP's nested form: the outer count caps
    assert threads.workers() == 3
    clean_env.setenv("OMP_NUM_THREADS", "auto")  # not a count: ignored
    assert threads.workers() == threads.MOST_WORKERS
    clean_env.setenv("PYCINDER_THREADS", "12")  # pycinder's own setting wins
    assert threads.workers() == 12
    for bad in ("0", "two", "-1"):
        clean_env.setenv("PYCINDER_THREADS", bad)
        with pytest.raises(ValueError, match="PYCINDER_THREADS must be a whole number"):
            threads.workers()


def test_one_thread_means_no_pool():
    env = {**os.environ, "PYCINDER_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", "from pycinder.util import threads; "
                          "print(threads.WORKERS, threads.pool())"],
                         env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["1", "None"]
