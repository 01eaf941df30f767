"""Issue #24, environments as they are: a read-only installation and an unwritable home.

The finding: with the package folders and the home folder unwritable numba could not cache the
compiled kernels and every import of a kernel module raised (exit 1 on every run, so a shared
or system-wide installation could not be used).  The installation is simulated by a copy of
the package whose kernel folders have a *file* named ``__pycache__`` (so nothing can be cached
beside the sources, even as root), and the home and cache folders lie under a regular file
(so they cannot be created, even as root).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PROBE = textwrap.dedent("""
    import json, sys, tempfile
    if len(sys.argv) > 2:       # the system's temporary folder too (no fallback to /tmp)
        tempfile.tempdir = sys.argv[2]
    import flightrecon
    from flightrecon import numba_cache
    from flightrecon.pipeline import METHOD_FUNCTIONS
    import importlib
    for mod, _ in METHOD_FUNCTIONS.values():   # decorating the kernels needs a cache locator
        importlib.import_module(mod)
    sys.path.insert(0, sys.argv[1])
    import tinykernel                           # one small cached kernel, compiled and saved
    assert tinykernel.twice(21.0) == 42.0
    print(json.dumps(numba_cache.CHOICE))
""")

KERNEL = textwrap.dedent("""
    import numba
    @numba.njit(cache=True)
    def twice(x):
        return 2.0 * x
""")


@pytest.fixture(scope="module")
def readonly_install(tmp_path_factory) -> Path:
    base = tmp_path_factory.mktemp("install")
    shutil.copytree(ROOT / "flightrecon", base / "flightrecon",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for d in [base / "flightrecon", *[p for p in (base / "flightrecon").rglob("*")
                                      if p.is_dir()]]:
        (d / "__pycache__").write_text("not a folder: nothing can be cached here\n")
    kdir = base / "kernels"
    kdir.mkdir()
    (kdir / "tinykernel.py").write_text(KERNEL)
    (kdir / "__pycache__").write_text("not a folder\n")
    return base


def _run(install: Path, env_extra: dict[str, str], tempdir: str | None = None
         ) -> subprocess.CompletedProcess:
    blocker = install / "blocker"
    blocker.write_text("a file: nothing can be created below it\n")
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "PYTHONPATH")}
    env.update({"PYTHONPATH": str(install), "HOME": str(blocker / "home"),
                "XDG_CACHE_HOME": str(blocker / "cache"), "PYTHONDONTWRITEBYTECODE": "1"})
    env.update(env_extra)
    args = [str(install / "kernels")] + ([tempdir] if tempdir else [])
    return subprocess.run([sys.executable, "-c", PROBE, *args],
                          capture_output=True, text=True, env=env, timeout=600, check=False,
                          cwd=install)


def test_readonly_installation_with_unwritable_home_runs(readonly_install, tmp_path):
    """The kernels are cached in a private temporary folder instead."""
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    p = _run(readonly_install, {"TMPDIR": str(tmpdir)})
    assert p.returncode == 0, p.stderr[-3000:]
    choice = json.loads(p.stdout.strip().splitlines()[-1])
    assert choice["how"] == "temporary"
    assert Path(choice["path"]).parent == tmpdir
    assert any(Path(choice["path"]).rglob("*.nbi"))     # the kernel's cache index was saved


def test_readonly_installation_uses_the_user_cache_dir(readonly_install, tmp_path):
    cache = tmp_path / "usercache"
    p = _run(readonly_install, {"XDG_CACHE_HOME": str(cache)})
    assert p.returncode == 0, p.stderr[-3000:]
    choice = json.loads(p.stdout.strip().splitlines()[-1])
    assert choice["how"] == "user cache"
    assert Path(choice["path"]) == cache / "flightrecon" / "numba"


def testnumba_cache_dir_is_honoured(readonly_install, tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    p = _run(readonly_install, {"NUMBA_CACHE_DIR": str(mine)})
    assert p.returncode == 0, p.stderr[-3000:]
    choice = json.loads(p.stdout.strip().splitlines()[-1])
    assert choice == {"how": "NUMBA_CACHE_DIR", "path": str(mine)}
    assert any(mine.rglob("*.nbi"))


def test_no_writable_folder_at_all_runs_without_a_cache_with_a_notice(readonly_install):
    blocker = readonly_install / "blocker"
    p = _run(readonly_install, {}, tempdir=str(blocker / "tmp"))
    assert p.returncode == 0, p.stderr[-3000:]
    choice = json.loads(p.stdout.strip().splitlines()[-1])
    assert choice["how"] == "none"
    assert "notice" in p.stderr and "NUMBA_CACHE_DIR" in p.stderr
