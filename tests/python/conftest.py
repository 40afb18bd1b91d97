"""Shared set-up of the Python module's tests: the build's package and command, the demo assets,
a scratch directory. Run by ctest (test `python`) as /usr/bin/python3 -m pytest tests/python."""
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("PRTBAKE_BUILD_DIR", ROOT / "build"))
CLI = BUILD / "prtbake"
ASSETS = ROOT / "assets"
DATA = pathlib.Path(os.environ.get("PRTBAKE_DATA_DIR", ROOT.parent / "shared" / "data"))


def cli(*args, check=True):
    """Runs the prtbake command of the same build; returns the completed process."""
    env = dict(os.environ, PRTBAKE_DEVICE=os.environ.get("PRTBAKE_DEVICE", "cpu"))
    p = subprocess.run([str(CLI), *map(str, args), "--quiet"], capture_output=True, text=True, env=env, timeout=600)
    if check and p.returncode != 0:
        raise AssertionError("prtbake %s failed: %s" % (" ".join(map(str, args)), p.stderr))
    return p


def data(*parts):
    """A file of the shared data, or a skip saying it is absent (PRTBAKE_FORBID_SKIPS makes that a failure)."""
    path = DATA.joinpath(*parts)
    if not path.exists():
        if os.environ.get("PRTBAKE_FORBID_SKIPS"):
            pytest.fail("%s is absent (PRTBAKE_FORBID_SKIPS is set)" % path)
        pytest.skip("%s is absent (../shared/data)" % path)
    return path


def pytest_runtest_logreport(report):
    """Skipped tests are listed with their reason after ctest's summary (scripts/test.sh)."""
    log = os.environ.get("PRTBAKE_SKIP_LOG")
    if report.skipped and log:
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        with open(log, "a") as f:
            f.write("python %s: %s\n" % (report.nodeid, reason))
