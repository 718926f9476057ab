"""The memory check: a request larger than the available memory is refused with its estimate, before work."""

import pytest

from infonav_gym import memory


def test_available_memory_is_linuxs_memavailable(tmp_path, monkeypatch):
    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   20000000 kB\n")
    monkeypatch.setattr(memory, "MEMINFO", meminfo)
    assert memory.available_bytes() == 20_000_000 * 1024


def test_a_request_beyond_the_available_memory_is_refused_with_its_estimate(monkeypatch):
    monkeypatch.setattr(memory, "available_bytes", lambda: 2e9)
    memory.check_memory(1.9e9, "num_envs=1000")
    with pytest.raises(ValueError, match=r"^num_envs=10\*\*7 needs about 52.0 GB of memory; 2.0 GB are available$"):
        memory.check_memory(52e9, "num_envs=10**7")


def test_an_unknown_available_memory_refuses_nothing(monkeypatch):
    monkeypatch.setattr(memory, "available_bytes", lambda: None)
    memory.check_memory(1e15, "anything")
