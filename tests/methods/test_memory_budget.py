"""An input larger than the memory available is refused before the work starts, with the size that fits."""

from __future__ import annotations

import numpy as np
import pytest

import parambench.methods.memory_budget as memory_budget
from parambench.bench.cli import main
from parambench.datasets_gen.errors import ResourceLimitError
from parambench.datasets_gen.registry import make_surface
from parambench.methods.memory_budget import MEMORY_CHECK_ENV, PeakMemory, available_bytes, check_memory
from parambench.methods.pointset.params import FRONTEND_PEAK
from parambench.methods.pointset.plugin_support import FRONTEND_DEFAULTS
from parambench.methods.registry import get_method, method_names


def _fake_system(tmp_path, available_kb: int, cgroup: dict[str, str]):
    meminfo = tmp_path / "meminfo"
    meminfo.write_text(f"MemTotal:       24683772 kB\nMemFree:        1000 kB\nMemAvailable:   {available_kb} kB\n")
    root = tmp_path / "cgroup"
    for name, text in cgroup.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text + "\n")
    return meminfo, root


@pytest.mark.parametrize("cgroup,expected_gib", [
    ({}, 8.0),  # no cgroup files: MemAvailable
    ({"memory.max": "max", "memory.current": "123"}, 8.0),  # cgroup v2 without a limit
    ({"memory.max": str(6 * 2**30), "memory.current": str(2**30)}, 5.0),  # v2 limit less usage, under MemAvailable
    ({"memory.max": str(64 * 2**30), "memory.current": str(2**30)}, 8.0),  # a limit above MemAvailable
    ({"memory/memory.limit_in_bytes": str(2**63 - 4096), "memory/memory.usage_in_bytes": "5"}, 8.0),  # v1, none
    ({"memory/memory.limit_in_bytes": str(3 * 2**30), "memory/memory.usage_in_bytes": str(2**30)}, 2.0),  # v1
])
def test_available_memory_is_the_smaller_of_the_kernel_s_and_the_cgroup_s(tmp_path, cgroup, expected_gib):
    meminfo, root = _fake_system(tmp_path, 8 * 2**20, cgroup)
    assert available_bytes(meminfo=meminfo, cgroup=root) == expected_gib * 2**30


def test_nothing_readable_means_unknown(tmp_path):
    assert available_bytes(meminfo=tmp_path / "none", cgroup=tmp_path / "none") is None


def test_check_memory_refuses_with_the_size_that_fits(monkeypatch):
    monkeypatch.delenv(MEMORY_CHECK_ENV, raising=False)
    linear = PeakMemory(1_000_000, 4.0 * 2**30, 1.0)
    check_memory("ocp", 1_000_000, linear, available=2**32)  # exactly 4 GiB of 4: fits
    with pytest.raises(ResourceLimitError) as err:
        check_memory("ocp", 3_000_000, linear, available=2**32)
    message = str(err.value)
    assert "3,000,000 points" in message and "about 12.0 GiB" in message and "4.0 GiB is available" in message
    assert "at most about 1,000,000" in message and MEMORY_CHECK_ENV in message
    monkeypatch.setattr(memory_budget, "available_bytes", lambda: None)
    check_memory("ocp", 3_000_000, linear)  # unknown: not checked
    monkeypatch.setenv(MEMORY_CHECK_ENV, "0")
    check_memory("ocp", 3_000_000, linear, available=2**32)  # switched off


def test_a_superlinear_growth_is_followed():
    """Growth n^1.5: 4x the points need 8x the memory; the size that fits inverts the estimate."""
    peak = PeakMemory(100_000, 1e9, 1.5)
    assert peak.at(400_000) == pytest.approx(8e9)
    assert abs(peak.points_within(8e9) - 400_000) <= 1  # rounded down
    assert peak.at(peak.points_within(3e9)) <= 3e9 < peak.at(peak.points_within(3e9) + 1)


def test_the_methods_that_state_their_memory_state_a_measurement():
    """ocp (the point-set default) and scp-igl (the baseline) state theirs: between 1 and 100 KB
    a point at a million points, growing between linearly and as n^1.5."""
    stated = {name: get_method(name).peak_memory for name in method_names()}
    assert stated["ocp"] is not None and stated["scp-igl"] is not None
    for peak in filter(None, stated.values()):
        assert 1e3 < peak.at(1_000_000) / 1e6 < 1e5 and 1.0 <= peak.exponent <= 1.5
    # Every method with the point-set front end needs at least the front end's memory.
    for name in method_names():
        method = get_method(name)
        if set(FRONTEND_DEFAULTS) <= set(method.defaults):
            assert method.peak_memory is not None and method.peak_memory.at(10**6) >= FRONTEND_PEAK.at(10**6), name


@pytest.fixture
def one_mib_left(monkeypatch, tmp_path):
    """2,000 random points on bump (and the same as an .xyz file), with 1 MiB 'available'."""
    monkeypatch.delenv(MEMORY_CHECK_ENV, raising=False)
    monkeypatch.setattr(memory_budget, "available_bytes", lambda: 2**20)
    surface = make_surface("bump", 2000, sampling="random", seed=0).points_only()
    src = tmp_path / "cloud.xyz"
    np.savetxt(src, surface.points)
    return surface, src


def test_ocp_is_refused_before_it_starts_and_flatten_says_so_in_one_line(one_mib_left, monkeypatch, tmp_path, capsys):
    """With 1 MiB 'available', 2,000 points are too many for ocp: refused at once (no front end
    ran: no stage timings were started), and `flatten` exits 2 with the message on one line."""
    surface, src = one_mib_left
    with pytest.raises(ResourceLimitError, match="thin the points to at most about"):
        get_method("ocp")(surface)
    assert main(["flatten", str(src), "-o", str(tmp_path / "uv.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs about" in err[0] and "GiB is available" in err[0]
    assert not (tmp_path / "uv.csv").exists()
    monkeypatch.setenv(MEMORY_CHECK_ENV, "0")
    assert get_method("ocp")(surface).uv.shape == (surface.n_points, 2)


def test_inspect_and_the_other_point_set_methods_are_refused_on_the_front_end_s_share(one_mib_left, tmp_path, capsys):
    """The front end alone needs more than 1 MiB for 2,000 points: `inspect` exits 2 (no JSON
    written), and sdp says it needs at least the front end's share."""
    surface, src = one_mib_left
    assert main(["inspect", str(src), "-o", str(tmp_path / "fe.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs at least" in err[0] and "front end alone" in err[0]
    assert not (tmp_path / "fe.json").exists()
    with pytest.raises(ResourceLimitError, match="sdp on 2,000 points needs at least"):
        get_method("sdp")(surface)
