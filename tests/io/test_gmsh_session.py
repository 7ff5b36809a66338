"""gmsh must not change the signal handlers of the process that uses it (a piped
test run was killed by SIGPIPE after a test had initialized gmsh)."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

from meshopt_toolkit.gmsh_session import gmsh_session

ROOT = Path(__file__).resolve().parents[2]


def _kernel_ignored_signals() -> set[int]:
    status = Path("/proc/self/status")
    if not status.exists():
        pytest.skip("needs /proc/self/status (Linux) to read the kernel's signal dispositions")
    for line in status.read_text().splitlines():
        if line.startswith("SigIgn:"):
            mask = int(line.split()[1], 16)
            return {s for s in range(1, 65) if mask >> (s - 1) & 1}
    raise AssertionError("no SigIgn line")


def test_session_keeps_sigpipe_ignored_and_ctrl_c_raising():
    pytest.importorskip("gmsh")
    assert signal.SIGPIPE in _kernel_ignored_signals()  # Python ignores SIGPIPE at start-up
    sigint = signal.getsignal(signal.SIGINT)
    with gmsh_session() as gmsh:
        gmsh.model.add("probe")
        assert signal.SIGPIPE in _kernel_ignored_signals()
        assert signal.getsignal(signal.SIGINT) is sigint
    assert signal.SIGPIPE in _kernel_ignored_signals()
    assert signal.getsignal(signal.SIGINT) is sigint


def test_plain_gmsh_initialize_does_reset_sigpipe():
    """The reason for gmsh_session: without it the disposition changes (checked in a child,
    so this process keeps its handlers). If gmsh ever stops doing this, the wrapper may go."""
    pytest.importorskip("gmsh")
    code = ("import gmsh\n"
            "gmsh.initialize(readConfigFiles=False, interruptible=False)\n"
            "line = [l for l in open('/proc/self/status') if l.startswith('SigIgn:')][0]\n"
            "print(int(line.split()[1], 16) >> 12 & 1)\n")
    if not Path("/proc/self/status").exists():
        pytest.skip("needs /proc/self/status")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, check=True).stdout.split()
    assert out[-1] == "0"


def test_gmsh_is_initialized_only_through_the_session():
    offenders = []
    for path in [*ROOT.glob("meshopt_toolkit/**/*.py"), *ROOT.glob("tests/**/*.py"), *ROOT.glob("benchmarks/*.py"),
                 *ROOT.glob("examples/*.py")]:
        if path.name in {"gmsh_session.py", Path(__file__).name}:
            continue
        if "gmsh.initialize(" in path.read_text():
            offenders.append(str(path.relative_to(ROOT)))
    assert offenders == []
