"""The benchmark suites are runnable by airspeed velocity (``benchmarks/asv.conf.json``)."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_asv_discovers_every_benchmark_without_a_problem():
    """``asv check`` imports every module of benchmarks/ and checks each ``time_*`` /
    ``track_*`` it finds has the right signature (a helper named ``time_…`` fails it)."""
    pytest.importorskip("asv")
    exe = shutil.which("asv") or [sys.executable, "-m", "asv"]
    cmd = [exe] if isinstance(exe, str) else exe
    proc = subprocess.run(
        [*cmd, "check", "--config", str(ROOT / "benchmarks" / "asv.conf.json"), "--python=same"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "No problems found" in proc.stdout
